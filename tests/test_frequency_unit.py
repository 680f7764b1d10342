"""Normalised frequency (rad/sample): the data say so and the diagnostics use samples."""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.fitting.diagnostics import check_delay, check_roots_below_band
from freqid_casadi.errors import DataError
from freqid_casadi.studies.robot_arm import arm_data


def test_unit_is_checked_and_kept_by_window_and_weights():
    w = np.linspace(0.1, 3.0, 20)
    d = fc.FrequencyData(w, 1 / (1 + 1j * w), unit="rad/sample")
    assert d.time_unit == "samples" and fc.FrequencyData(w, 1 + 0 * w).time_unit == "s"
    assert d.window(5).unit == "rad/sample" and d.with_weights(np.ones(20)).unit == d.unit
    with pytest.raises(DataError, match="unit must be one of"):
        fc.FrequencyData(w, 1 + 0 * w, unit="Hz")


def test_robot_arm_delay_diagnostics_are_in_samples():
    # the measured report said "the delay 0.322565 s ... 9.23e+04 s" for a delay in samples
    _, data = arm_data()
    assert data.unit == "rad/sample"
    beta = [0.5, 1.0, 1.0, 0.3, 1.0, 1.0, 0.05, 0.5]
    model = fc.RationalDelayModel(fc.Structure(1, delay=True), beta)
    (diag,) = check_delay(model, data, delay_max=3.0, delay_std=10.0)
    assert "0.5 samples" in diag.message and "10 samples" in diag.message
    assert " s " not in diag.message and "rad/s" not in diag.message
    low = fc.RationalDelayModel(fc.Structure(1, delay=True),
                                [0.5, 1.0, 1.0, 0.3, 1e-6, 1.0, 0.05, 0.5])
    (below,) = check_roots_below_band(low, data)
    assert "rad/sample" in below.message and "rad/s " not in below.message


def test_report_of_a_normalised_fit_speaks_rad_per_sample(tmp_path):
    # summary.md and the figures of a fit to rad/sample data said rad/s, Hz and s
    import json

    import matplotlib

    matplotlib.use("Agg")
    from freqid_casadi.report.folder import write_fit_report

    _, data = arm_data()
    res = fc.fit(data, n_sections=2, progress=False)
    write_fit_report(res, tmp_path / "rep", command="test")
    text = (tmp_path / "rep" / "summary.md").read_text()
    assert "rad/sample" in text and "samples" in text
    assert "rad/s " not in text and "rad/s)" not in text and " Hz" not in text
    js = json.loads((tmp_path / "rep" / "summary.json").read_text())
    assert js["data"]["unit"] == "rad/sample" and "f_min_hz" not in js["data"]


def test_frf_csv_without_fs_round_trips_its_unit(tmp_path, capsys):
    # freqid frf without --fs wrote 'omega,real,imag' in rad/sample, and freqid fit then
    # read rad/s: its report gave the delay in s
    from freqid_casadi.cli.app import main
    from freqid_casadi.io.loaders import load, save_csv

    w = np.linspace(0.05, 3.0, 30)
    d = fc.FrequencyData(w, np.exp(-0.5j * w) / (1 + 1j * w), unit="rad/sample")
    save_csv(d, tmp_path / "n.csv")
    assert (tmp_path / "n.csv").read_text().startswith("omega [rad/sample],real,imag\n")
    back = load(tmp_path / "n.csv")
    assert back.unit == "rad/sample" and np.array_equal(back.omega, w)
    save_csv(fc.FrequencyData(w, 1 + 0j * w), tmp_path / "s.csv")
    assert load(tmp_path / "s.csv").unit == "rad/s"
    assert main(["fit", str(tmp_path / "n.csv"), "--sections", "1", "--out",
                 str(tmp_path / "rep"), "--quiet"]) == 0
    out = capsys.readouterr()
    import re

    assert re.search(r"delay [0-9.e+-]+ samples, ", out.out + out.err)

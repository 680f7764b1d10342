"""The noisy-data study (freqid_casadi.studies.noisy and noisy_report) on a small problem:
the report folder, its first line, and report.md's numbers against report.json (the
robot-arm study is tested in test_robot_arm.py)."""

import matplotlib

matplotlib.use("Agg")

import pytest  # noqa: E402

from freqid_casadi.errors import OptionError  # noqa: E402
from freqid_casadi.report.formatting import generated_by_line, number  # noqa: E402
from freqid_casadi.studies.noisy_report import write_noisy_report  # noqa: E402


def test_noisy_report_refuses_existing_folder(tmp_path):
    (tmp_path / "noisy").mkdir()
    with pytest.raises(OptionError, match="exists; pass --force"):
        write_noisy_report(tmp_path / "noisy", command="x", n_sections=1)


@pytest.mark.slow
def test_noisy_report_small(tmp_path):
    out = tmp_path / "noisy"
    s = write_noisy_report(out, command="python scripts/noisy_example.py --sections 3",
                           n_sections=3)
    assert sorted(p.name for p in out.iterdir()) == [".freqid-output", "clean_error.png",
                                                      "report.json", "report.md", "weights.png"]
    md = (out / "report.md").read_text(encoding="utf-8")
    assert md.splitlines()[0] == generated_by_line(
        "python scripts/noisy_example.py --sections 3")
    a = s["noisy"]
    assert a["n_sections"] == 3 and s["n_points"] == 500 and s["n_dense"] == 5000
    # the noise is the seeded 2 % realisation, measured
    assert s["noise_rms"] == pytest.approx(0.02, rel=0.1)
    assert f"RMS {number(s['noise_rms'])}, max |n| {number(s['noise_max'])}" in md
    assert s["weights_effect"] in md

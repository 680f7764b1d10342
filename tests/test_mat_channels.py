"""A ``.mat`` file of several responses: an FRF matrix beside one frequency vector (``H``,
N x channels or channels x N; MATLAB ``modalfrf``'s ``frf``, N x outputs x inputs) or
several complex vectors (``H11``, ``H21``). ``load`` reads one (``parameter='H(:,3)'``)
and says how to choose; ``load_all`` and ``freqid modal`` read every one.

The files are written as MATLAB writes them (``save(..., '-v7')``, through scipy.io).
"""

import json
import os
import warnings

import numpy as np
import pytest
import scipy.io

import freqid_casadi as fc
from freqid_casadi.cli import main
from freqid_casadi.errors import DataError

F = np.linspace(1.0, 10.0, 40)
#: 6 channels: first-order lags of corner 1..6 Hz, column k is channel k + 1
H = 1.0 / (1.0 + 1j * F[:, None] / np.arange(1.0, 7.0))


def _mat(tmp_path, name="test.mat", **variables):
    path = tmp_path / name
    scipy.io.savemat(str(path), variables)
    return path


@pytest.mark.parametrize("stored, names", [
    (H, [f"H(:,{k})" for k in range(1, 7)]),
    (H.T, [f"H({k},:)" for k in range(1, 7)]),
    # modalfrf's N x outputs x inputs (3 outputs, 2 inputs), MATLAB's column-major order
    (H.reshape(40, 3, 2, order="F"), [f"H(:,{i},{j})" for j in (1, 2) for i in (1, 2, 3)]),
])
def test_every_channel_of_a_matrix_is_read_and_named_as_matlab_indexes_it(tmp_path, stored,
                                                                           names):
    path = _mat(tmp_path, freq_hz=F, H=stored)
    datas = fc.load_all(path)
    assert [d.name for d in datas] == names
    np.testing.assert_array_equal(np.array([d.response for d in datas]).T, H)
    np.testing.assert_allclose(datas[0].omega, 2 * np.pi * F, rtol=1e-15)
    # load reads one, chosen by its MATLAB name
    third = fc.load(path, parameter=names[2])
    np.testing.assert_array_equal(third.response, H[:, 2])
    np.testing.assert_array_equal(third.omega, datas[2].omega)


def test_load_of_a_matrix_says_how_to_choose_one_or_read_all(tmp_path):
    path = _mat(tmp_path, f=F, frf=H)
    with pytest.raises(DataError, match=r"holds 6 responses \(frf \(40 x 6\): one per channel "
                       r"beside the frequencies\), not one: choose one with "
                       r"parameter='frf\(:,1\)' \.\.\. 'frf\(:,6\)' \(command line --parameter "
                       r"'frf\(:,1\)'\), or read them all with freqid_casadi\.load_all"):
        fc.load(path, freq_unit="Hz")
    with pytest.raises(DataError, match=r"no variable 'H'; its arrays: frf, frf\(:,1\), "
                       r".*frf\(:,6\), f: pass one"):
        fc.load(path, freq_unit="Hz", parameter="H")
    assert fc.load(path, freq_unit="Hz", parameter="frf(:,6)").response[0] == H[0, 5]


def test_several_complex_vectors_and_single_responses(tmp_path):
    path = _mat(tmp_path, freq_hz=F, H11=H[:, 0], H21=H[:, 1])
    assert [d.name for d in fc.load_all(path)] == ["H11", "H21"]
    # one response: load_all gives what load gives
    path = _mat(tmp_path, "one.mat", freq_hz=F, response=H[:, 3])
    (only,) = fc.load_all(path)
    np.testing.assert_array_equal(only.response, fc.load(path).response)
    assert only.name == "one"
    # a text file: the one response load reads
    csv = tmp_path / "x.csv"
    fc.save_csv(only, csv)
    (same,) = fc.load_all(csv)
    np.testing.assert_array_equal(same.response, only.response)
    # band applies to each channel
    path = _mat(tmp_path, "m.mat", freq_hz=F, H=H)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", fc.DataWarning)
        cut = fc.load_all(path, band=(2.0, 5.0))
    assert len(cut) == 6 and all(d.n_points == int(np.sum((F >= 2) & (F <= 5))) for d in cut)


def test_freqid_modal_reads_every_channel_of_an_frf_matrix(tmp_path, capsys):
    # two well-separated modes seen by three sensors, stored as MATLAB's modalfrf writes
    # its output: frf (N x 3) beside f (Hz)
    f = np.linspace(0.5, 6.0, 160)
    s = 2j * np.pi * f
    shapes = np.array([[1.0, 0.6], [0.7, -0.5], [0.4, -0.9]])
    poles = [(2 * np.pi * 1.5, 0.02), (2 * np.pi * 4.0, 0.01)]
    frf = sum(np.outer(1.0 / (s * s + 2 * z * p * s + p * p), shapes[:, k] * shapes[0, k])
              for k, (p, z) in enumerate(poles))
    path = _mat(tmp_path, f=f, frf=frf)
    out = tmp_path / "rep"
    # (free zeros, the default: the third sensor's FRF has a right-half-plane zero)
    assert main(["modal", str(path), "--freq-unit", "hz", "--orders", "2:8:2",
                 "--min-stable", "2", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_modes_selected"] == 2
    assert [m["omega_n"] for m in summary["modes"]] == pytest.approx(
        [p for p, _ in poles], rel=1e-6)
    assert summary["channels"] == ["frf_1", "frf_2", "frf_3"]
    assert summary["top_order"]["rhp_zeros_in_band"] == {"frf_1": False, "frf_2": False,
                                                         "frf_3": True}
    assert "| frf_3 | " in (out / "summary.md").read_text()
    assert {"bode_frf_1.png", "bode_frf_2.png", "bode_frf_3.png"} <= set(os.listdir(out))
    # --parameter: that channel alone
    assert main(["modal", str(path), "--freq-unit", "hz", "--parameter", "frf(:,2)",
                 "--orders", "2:6:2", "--min-stable", "2", "--zeros", "free",
                 "--out", str(tmp_path / "one")]) == 0
    one = json.loads((tmp_path / "one" / "summary.json").read_text())
    assert one["channels"] == ["test"]


def test_a_frequency_vector_named_outside_the_vocabulary_is_the_axis(tmp_path):
    # published layouts: an EMA demo's FRF (32 x 9) beside frequencyBand (uint8, 0:5:155
    # Hz, a column); a course's G_exp (N x 6) beside freqs (a row)
    band = np.arange(0, 160, 5, dtype=np.uint8).reshape(-1, 1)
    frf = 1.0 / (1.0 + 1j * band / np.arange(1.0, 10.0))
    path = _mat(tmp_path, "ema.mat", FRF=frf, frequencyBand=band)
    with pytest.raises(DataError, match=r"the unit of the frequency variable frequencyBand is "
                       r"unknown: pass freq_unit='Hz'"):
        fc.load_all(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", fc.DataWarning)     # the 0 Hz row is dropped
        datas = fc.load_all(path, freq_unit="Hz")
    assert [d.name for d in datas] == [f"FRF(:,{k})" for k in range(1, 10)]
    assert datas[0].n_points == 31
    np.testing.assert_allclose(datas[8].omega, 2 * np.pi * band[1:, 0], rtol=1e-15)
    np.testing.assert_array_equal(datas[8].response, frf[1:, 8])
    path = _mat(tmp_path, "cant.mat", G_exp=H, freqs=F.reshape(1, -1))
    assert len(fc.load_all(path, freq_unit="Hz")) == 6
    # a vector that is not increasing is no axis
    path = _mat(tmp_path, "bad.mat", G_exp=H, freqs=F[::-1].copy())
    with pytest.raises(DataError):
        fc.load_all(path, freq_unit="Hz")


def test_load_all_reads_several_real_and_imaginary_pairs_beside_one_axis(tmp_path):
    # H21 and H22 as N x 2 (real, imaginary) beside f_start, df and f_end
    h = np.column_stack([H[:, 0].real, H[:, 0].imag])
    path = _mat(tmp_path, "H2.mat", H21=h, H22=2 * h, df=1.0, f_start=1.0, f_end=40.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", fc.DataWarning)
        datas = fc.load_all(path, freq_unit="Hz")
    assert [d.name for d in datas] == ["H21", "H22"]
    np.testing.assert_array_equal(datas[1].response, 2 * H[:, 0])


def test_complex_matrices_without_frequencies_say_so(tmp_path):
    path = _mat(tmp_path, "mob.mat", mobilityMatrix=H)
    with pytest.raises(DataError, match=r"holds complex responses but no frequency variable "
                       r"\(found mobilityMatrix \(40 x 6, complex\)\): save the frequencies"):
        fc.load_all(path, freq_unit="Hz")


def test_a_channel_name_with_a_space_or_out_of_range(tmp_path):
    path = _mat(tmp_path, f=F, frf=H)
    one = fc.load(path, freq_unit="Hz", parameter="frf(:, 2)")
    np.testing.assert_array_equal(one.response, H[:, 1])
    with pytest.raises(DataError, match=r"'frf\(:,7\)' is not a channel of frf \(40 x 6\): "
                       r"its channels are frf\(:,1\) \.\.\. frf\(:,6\) \(6\)"):
        fc.load(path, freq_unit="Hz", parameter="frf(:,7)")


def test_modal_report_words_the_advice_as_options():
    from freqid_casadi.cli.modal import modal_words

    assert modal_words("— pass n_sections=4 or more for a mode the shared poles miss, or "
                       "channel_sections=1 for modes outside the band") == (
        "— pass --orders reaching 8 or more for a mode the shared poles miss, or "
        "--channel-sections 1 for modes outside the band")
    assert modal_words("pass zeros='free' (freqid modal --zeros free)") == "pass --zeros free"


def test_spectra_saved_beside_the_frf_are_named_and_not_read_as_responses(tmp_path):
    # an analyser's export (a vibration toolbox's case file): the FRF Hf_chan_2 beside its
    # cross-spectrum, coherence, PSDs and time records; load read nothing ("cannot tell
    # the variables apart") and load_all gave the cross-spectrum as a second channel
    rng = np.random.default_rng(3)
    f = np.arange(0.0, 40 * 0.3125, 0.3125)
    frf = 1.0 / (1.0 + 1j * f / 4.0)
    path = _mat(tmp_path, Time_domain=np.arange(128) / 100.0,
                Time_chan_1=rng.standard_normal(128), Time_chan_2=rng.standard_normal(128),
                Freq_domain=f, PSD_chan_1=np.abs(frf), Hf_chan_2=frf,
                Hf_coh_chan_2=np.ones(f.size), Hf_Cross_Spec_chan_2=frf * 3.0)
    with pytest.warns(fc.io.loaders.DataWarning, match=r"read Hf_chan_2 as the response; not "
                      r"read: Hf_Cross_Spec_chan_2 \(a cross-spectrum\)"):
        data = fc.load(path, freq_unit="Hz")
    np.testing.assert_array_equal(data.response, frf[1:])            # (0 Hz dropped)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        datas = fc.load_all(path, freq_unit="Hz")
    assert len(datas) == 1 and np.array_equal(datas[0].response, frf[1:])
    # two FRFs and a coherence: load says how to choose, load_all reads the two
    both = _mat(tmp_path, "h1h2.mat", freq=F, H1=H[:, 0], H2=H[:, 1], coh=H[:, 2])
    with pytest.raises(DataError, match=r"holds 3 complex vectors \(H1, H2, coh \(a "
                       r"coherence\)\), not one response: choose the response with "
                       r"parameter='H1' \(command line --parameter H1\), or read every one "
                       r"with freqid_casadi\.load_all"):
        fc.load(both, freq_unit="Hz")
    with pytest.warns(fc.io.loaders.DataWarning, match=r"not read: coh \(a coherence\)"):
        datas = fc.load_all(both, freq_unit="Hz")
    assert [d.name for d in datas] == ["H1", "H2"]


@pytest.mark.parametrize("name, kind", [
    ("Hf_Cross_Spec_chan_2", "cross-spectrum"), ("meas.Gxy1", "cross-spectrum"),
    ("coh", "coherence"), ("crossSpectrum", "cross-spectrum"), ("PSD_chan_1", None),
    # "cross", "power", "auto" alone name no spectrum (a review's H_power_amp beside H_motor
    # lost one of two responses)
    ("H_cross_axis", None), ("H_power_amp", None), ("TF_auto_focus", None),
    ("H1", None), ("Hf_chan_2", None), ("frf(:,2)", None), ("H21", None), ("Txy", None),
    ("response", None)])
def test_spectrum_kind_reads_the_words_of_a_name(name, kind):
    from freqid_casadi.io._mat import spectrum_kind

    assert spectrum_kind(name) == kind


def test_one_matrix_of_frequency_real_imag_is_a_table_not_records(tmp_path):
    # [f, re, im] as one N x 3 matrix: refused as time records by the matrices' rule
    path = _mat(tmp_path, "m3.mat", data=np.c_[F, H[:, 0].real, H[:, 0].imag])
    data = fc.load(path, freq_unit="Hz")
    np.testing.assert_allclose(data.response, H[:, 0], rtol=1e-15)


def test_time_records_in_matrices_of_columns_point_to_freqid_frf(tmp_path):
    # a lab's shaker run: times (1 x N-1), inputvalues and outputvalues (N x 2 each)
    rng = np.random.default_rng(0)
    path = _mat(tmp_path, "run.mat", times=np.arange(299) / 1000.0,
                outputvalues=rng.standard_normal((300, 2)),
                inputvalues=rng.standard_normal((300, 2)))
    with pytest.raises(DataError, match=r"holds time records \(outputvalues\(:,1\), "
                       r"outputvalues\(:,2\), inputvalues\(:,1\), inputvalues\(:,2\): 300 "
                       r"samples each\), not a frequency response: estimate it with 'freqid "
                       r"frf FILE --u NAME --y NAME'"):
        fc.load(path)
    # its time vector, one stamp short of the records, gives the sampling rate (noted)
    from freqid_casadi.experiment import load_records_mat

    with pytest.warns(fc.io.loaders.DataWarning, match=r"the sampling rate 1000 Hz from the "
                      r"steps of times \(299 stamps for 300 samples\)"):
        rec = load_records_mat(str(path))
    assert rec.fs == pytest.approx(1000.0, rel=1e-12)


def test_an_npz_archive_another_program_wrote_is_read_by_its_arrays_names(tmp_path):
    # a Raspberry Pi vibration logger's archive: freq (Hz), H1 and H2 (complex64), the
    # coherence, and the int16 time records; refused before ("lacks array(s) ['omega',
    # 'response']") whatever the options
    rng = np.random.default_rng(1)
    h1 = H[:, 0].astype(np.complex64)
    path = tmp_path / "test.npz"
    np.savez(path, input=rng.integers(-99, 99, 500).astype(np.int16),
             output=rng.integers(-99, 99, 500).astype(np.int16), freq=F, H1=h1,
             H2=H[:, 1].astype(np.complex64), coh=np.ones(F.size, np.complex64))
    with pytest.raises(DataError, match=r"holds 3 complex vectors \(H1, H2, coh \(a "
                       r"coherence\)\), not one response: choose the response with "
                       r"parameter='H1'"):
        fc.load(path, freq_unit="Hz")
    data = fc.load(path, freq_unit="Hz", parameter="H1")
    np.testing.assert_array_equal(data.response, h1)
    np.testing.assert_allclose(data.omega, 2 * np.pi * F, rtol=1e-15)
    with pytest.warns(fc.io.loaders.DataWarning, match=r"not read: coh \(a coherence\)"):
        assert [d.name for d in fc.load_all(path, freq_unit="Hz")] == ["H1", "H2"]
    # an FRF matrix without frequencies: refused saying what is missing
    bare = tmp_path / "building.npz"
    np.savez(bare, data=H)
    with pytest.raises(DataError, match=r"holds complex responses but no frequency variable "
                       r"\(found data \(40 x 6, complex\)\)"):
        fc.load(bare)
    # time records alone: pointed to freqid frf, which reads them as a .mat file's
    runs = tmp_path / "runs.npz"
    np.savez(runs, u=rng.standard_normal(256), y=rng.standard_normal(256), fs=100.0)
    with pytest.raises(DataError, match=r"holds time records \(u, y: 256 samples each\), not "
                       r"a frequency response: estimate it with 'freqid frf FILE --u NAME "
                       r"--y NAME'"):
        fc.load(runs)
    from freqid_casadi.experiment import load_records_mat

    rec = load_records_mat(str(runs))
    assert rec.fs == 100.0 and set(rec.channels) == {"u", "y"}
    assert main(["frf", str(runs), "--u", "u", "--y", "y", "--nperseg", "64",
                 "--out", str(tmp_path / "runs_frf.csv")]) == 0
    # the package's own format is read as before, its options refused
    own = tmp_path / "own.npz"
    np.savez(own, omega=2 * np.pi * F, response=H[:, 2])
    np.testing.assert_array_equal(fc.load(own).response, H[:, 2])
    with pytest.raises(fc.errors.OptionError, match=r"columns= names the columns .* names "
                       r"its own arrays: drop it"):
        fc.load(own, columns="f,re,im")

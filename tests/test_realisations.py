"""Several realisations of a periodic experiment averaged (``frf_from_realisations``,
``freqid frf`` on a .mat file whose records are matrices of realisations): the noise told
from the nonlinear distortions."""

import numpy as np
import pytest
import scipy.io
from scipy import signal

from freqid_casadi.cli import main
from freqid_casadi.errors import DataError
from freqid_casadi.experiment import frf_from_periodic, frf_from_realisations

N, FS = 256, 1000.0
B, A = signal.butter(2, 0.2)


def _records(R, P, nl, noise, seed=0, lines=np.arange(1, 60)):
    """R random-phase multisines over ``lines`` through a Butterworth filter (steady
    state), ``nl * y^2`` added and white output noise of ``noise`` times the output RMS."""
    rng = np.random.default_rng(seed)
    us, ys = [], []
    for _ in range(R):
        spec = np.zeros(N // 2 + 1, complex)
        spec[lines] = np.exp(2j * np.pi * rng.uniform(size=lines.size))
        u1 = np.fft.irfft(spec, N) * np.sqrt(N)
        y1 = signal.lfilter(B, A, np.tile(u1, P + 2))[2 * N:]
        ys.append(y1 + nl * y1 ** 2 + noise * np.std(y1) * rng.standard_normal(y1.size))
        us.append(np.tile(u1, P))
    return np.array(us), np.array(ys)


def _truth(omega):
    z = np.exp(1j * omega / FS)
    return np.polyval(B[::-1], 1 / z) / np.polyval(A[::-1], 1 / z)


def _rel_sd(est, var):
    return float(np.sqrt(np.median(var / np.abs(est.data.response) ** 2)))


def test_without_distortions_the_spread_over_realisations_is_the_noise():
    us, ys = _records(6, 4, 0.0, 0.01)
    est = frf_from_realisations(us, ys, N, fs=FS)
    assert est.n_realisations == 6 and est.n_periods == 4 and est.data.n_points == 59
    err = np.abs(est.data.response / _truth(est.data.omega) - 1)
    # measured: RMS error 0.0031, predicted 0.0028 (from the realisations), 0.0028 (noise)
    assert np.sqrt(np.mean(err ** 2)) < 0.005
    ratio = _rel_sd(est, est.variance) / _rel_sd(est, est.noise_variance)
    assert 0.6 < ratio < 1.5
    assert est.data.weights is not None and np.median(est.coherence) > 0.999


def test_distortions_show_as_spread_beyond_the_noise():
    us, ys = _records(6, 4, 0.02, 0.01)
    est = frf_from_realisations(us, ys, N, fs=FS)
    err = np.abs(est.data.response / _truth(est.data.omega) - 1)
    rms, total = np.sqrt(np.mean(err ** 2)), _rel_sd(est, est.variance)
    # measured: the estimate's RMS error 0.0073 against the truth; relative standard
    # deviation 0.0063 from the realisations, 0.0016 from the noise
    assert total > 2.5 * _rel_sd(est, est.noise_variance)
    assert 0.5 * total < rms < 2.0 * total


def test_one_realisation_is_frf_from_periodic():
    us, ys = _records(1, 3, 0.0, 0.01)
    a = frf_from_realisations(us, ys, N, fs=FS)
    b = frf_from_periodic(us[0], ys[0], N, fs=FS)
    np.testing.assert_array_equal(a.data.response, b.data.response)
    assert a.n_realisations is None


def test_realisations_exciting_different_lines_are_averaged_where_they_excite():
    # random-odd style: the first excites the odd lines 1..39, the second 21..59
    ua, ya = _records(1, 3, 0.0, 0.01, seed=1, lines=np.arange(1, 40, 2))
    ub, yb = _records(1, 3, 0.0, 0.01, seed=2, lines=np.arange(21, 60, 2))
    est = frf_from_realisations([ua[0], ub[0]], [ya[0], yb[0]], N, fs=FS)
    np.testing.assert_array_equal(est.bins, np.arange(1, 60, 2))
    alone = frf_from_periodic(ua[0], ya[0], N, fs=FS)
    np.testing.assert_array_equal(est.data.response[:10], alone.data.response[:10])
    np.testing.assert_array_equal(est.variance[:10], alone.variance[:10])
    err = np.abs(est.data.response / _truth(est.data.omega) - 1)
    assert np.max(err) < 0.05


def test_bad_realisations_are_named():
    us, ys = _records(3, 2, 0.0, 0.01)
    with pytest.raises(DataError, match="us holds 3 realisations and ys 2"):
        frf_from_realisations(us, ys[:2], N)
    bad = us.copy()
    bad[1, 5] = np.nan
    with pytest.raises(DataError, match=r"^realisation 2 of 3: "):
        frf_from_realisations(bad, ys, N)
    # one period each, lines only one of them excites: no variance (as one period alone)
    est = _one_period_odd()
    assert est.variance is None and est.data.weights is None and est.noise_variance is None
    assert est.data.n_points == 30


def _one_period_odd():
    ua, ya = _records(1, 1, 0.0, 0.01, seed=1, lines=np.arange(1, 40, 2))
    ub, yb = _records(1, 1, 0.0, 0.01, seed=2, lines=np.arange(21, 60, 2))
    return frf_from_realisations([ua[0], ub[0]], [ya[0], yb[0]], N)


def test_freqid_frf_averages_the_rows_or_columns_of_a_mat_file(tmp_path, capsys):
    us, ys = _records(4, 3, 0.02, 0.01)
    rows, cols = tmp_path / "rows.mat", tmp_path / "cols.mat"
    scipy.io.savemat(str(rows), {"uval": us, "yval": ys, "fs": FS})
    scipy.io.savemat(str(cols), {"u": us.T, "y": ys.T, "fs": FS})
    assert main(["frf", str(rows), "--u", "uval", "--y", "yval", "--period", str(N),
                 "--out", str(tmp_path / "a.csv")]) == 0
    out = capsys.readouterr().out
    assert "4 realisations of 3 period(s) each averaged" in out
    assert "nonlinear distortions" in out
    assert main(["frf", str(cols), "--period", str(N), "--out", str(tmp_path / "b.csv")]) == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert (tmp_path / "a.stats.csv").read_bytes() == (tmp_path / "b.stats.csv").read_bytes()
    # Welch cannot average realisations: choose one
    assert main(["frf", str(rows), "--u", "uval", "--y", "yval", "--out",
                 str(tmp_path / "c.csv")]) == 2
    assert "for --estimator h1 choose one, e.g. --u 'NAME(2,:)'" in capsys.readouterr().err
    assert main(["frf", str(rows), "--u", "uval(2,:)", "--y", "yval(2,:)", "--period",
                 str(N), "--out", str(tmp_path / "d.csv")]) == 0
    assert "3 period(s) averaged" in capsys.readouterr().out


def test_a_stated_rate_wins_over_a_time_vector_in_other_units(tmp_path, capsys):
    # a published motor bench: time counts microseconds (int32) before fs = 2500 (uint16);
    # the rate came from the time vector, 0.0025 Hz, and --fs 2500 was refused
    us, ys = _records(1, 3, 0.0, 0.01)
    t = (np.arange(us.size) * 400).astype(np.int32)
    path = tmp_path / "bench.mat"
    scipy.io.savemat(str(path), {"time": t, "iq": us[0], "theta": ys[0],
                                 "fs": np.uint16(2500)})
    assert main(["frf", str(path), "--u", "iq", "--y", "theta", "--period", str(N), "--fs",
                 "2500", "--out", str(tmp_path / "f.csv")]) == 0
    assert "omega 61.36 to 3620 rad/s" in capsys.readouterr().out      # 2 pi k 2500/256


def test_arrays_of_three_dimensions_and_mismatched_layouts_say_what_to_do(tmp_path, capsys):
    us, ys = _records(3, 2, 0.0, 0.01)
    path = tmp_path / "rpn.mat"
    scipy.io.savemat(str(path), {"u": us.reshape(3, 2, N), "y": ys.reshape(3, 2, N),
                                 "r": us[:, :N], "fs": FS})
    assert main(["frf", str(path), "--period", str(N), "--out", str(tmp_path / "a.csv")]) == 2
    assert ("--u 'u' is a 3 x 2 x 256 array, not a record or a matrix of realisations"
            in capsys.readouterr().err)
    with pytest.raises(DataError, match=r"us must be R x N \(one realisation of N samples a "
                       r"row\), got 3 x 2 x 256: for realisation x period x sample arrays "
                       r"pass us\.reshape\(R, -1\)"):
        frf_from_realisations(us.reshape(3, 2, N), ys, N)
    # a reference of one period per realisation beside records of two
    flat = tmp_path / "rn.mat"
    scipy.io.savemat(str(flat), {"u": us, "y": ys, "r": us[:, :N], "fs": FS})
    assert main(["frf", str(flat), "--period", str(N), "--reference", "r",
                 "--out", str(tmp_path / "b.csv")]) == 0
    assert "3 realisations of 2 period(s) each averaged" in capsys.readouterr().out
    # two files: one matrix each is read as its realisations; one record beside a matrix
    # of outputs is refused saying which to choose
    scipy.io.savemat(str(tmp_path / "U.mat"), {"uval": us})
    scipy.io.savemat(str(tmp_path / "Y.mat"), {"yval": ys})
    scipy.io.savemat(str(tmp_path / "U1.mat"), {"u": us[0]})
    assert main(["frf", "--u-file", str(tmp_path / "U.mat"), "--y-file",
                 str(tmp_path / "Y.mat"), "--period", str(N), "--fs", str(FS), "--out",
                 str(tmp_path / "c.csv")]) == 0
    assert (tmp_path / "c.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert main(["frf", "--u-file", str(tmp_path / "U1.mat"), "--y-file",
                 str(tmp_path / "Y.mat"), "--period", str(N), "--out",
                 str(tmp_path / "d.csv")]) == 2
    assert "the input is one record and the output a matrix of 3 records" in \
        capsys.readouterr().err


def test_a_one_period_reference_beside_a_single_record_is_repeated(tmp_path, capsys):
    # a generator's table of one period saved beside the records of several: it was
    # refused ("not a time record of the file") unless it was a matrix of realisations
    us, ys = _records(1, 4, 0.0, 0.0)
    rng = np.random.default_rng(5)
    u = us[0] + 1e-3 * rng.standard_normal(us[0].size)      # noise at every line
    full = frf_from_periodic(u, ys[0], N, fs=FS, reference=us[0])
    one = frf_from_periodic(u, ys[0], N, fs=FS, reference=us[0][:N])
    np.testing.assert_array_equal(one.bins, full.bins)
    np.testing.assert_array_equal(one.data.response, full.data.response)
    assert one.data.n_points == 59                      # the generated lines, not the noise
    with pytest.raises(DataError, match=r"reference must be a record as long as u \(1024 "
                       r"samples\) or one period \(256\), got shape \(100,\)"):
        frf_from_periodic(u, ys[0], N, fs=FS, reference=us[0][:100])
    path = tmp_path / "ms.mat"
    scipy.io.savemat(str(path), {"u": u, "y": ys[0], "r": us[0][:N], "fs": FS})
    assert main(["frf", str(path), "--period", str(N), "--reference", "r",
                 "--out", str(tmp_path / "a.csv")]) == 0
    assert "59 excited bins (1..59)" in capsys.readouterr().out

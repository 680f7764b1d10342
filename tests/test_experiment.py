"""Tests of freqid_casadi.experiment: time series -> frequency data (SPEC §7)."""

import os
import warnings

import numpy as np
import pytest
from scipy import signal

from freqid_casadi.core.data import FrequencyData
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.experiment import (
    FrfEstimate,
    actuator_records,
    dataset_path,
    frf_from_periodic,
    frf_from_records,
    frf_stepped_sine,
    load_daisy,
    load_daq_records,
    load_records_csv,
    robot_arm,
)

PERIOD = 256
ODD_BINS = np.arange(1, 100, 2)  # odd bins up to ~0.39 of the Nyquist band
# A stable 4th-order resonant filter (poles at radius 0.9 and 0.8).
B, A = signal.zpk2tf([-1, -1, 0.5, 0.5],
                     [0.9 * np.exp(0.4j), 0.9 * np.exp(-0.4j),
                      0.8 * np.exp(1.2j), 0.8 * np.exp(-1.2j)], 0.05)
B, A = np.real(B), np.real(A)


def multisine(period=PERIOD, bins=ODD_BINS, seed=0):
    """One period of an odd-bin multisine with random phases (fixed seed), RMS ~ 1."""
    rng = np.random.default_rng(seed)
    spec = np.zeros(period // 2 + 1, complex)
    spec[bins] = np.exp(2j * np.pi * rng.random(bins.size))
    u = np.fft.irfft(spec, period)
    return u / np.std(u)


def simulate(n_periods, seed=0):
    u = np.tile(multisine(seed=seed), n_periods)
    return u, signal.lfilter(B, A, u)


def true_response(bins, period=PERIOD):
    _, h = signal.freqz(B, A, worN=2 * np.pi * np.asarray(bins) / period)
    return h


# --------------------------------------------------------------------------- periodic

def test_multisine_recovers_filter_response():
    u, y = simulate(6)
    est = frf_from_periodic(u, y, PERIOD, skip_periods=2)
    assert isinstance(est, FrfEstimate)
    assert isinstance(est.data, FrequencyData)
    np.testing.assert_array_equal(est.bins, ODD_BINS)  # detected from the input spectrum
    assert est.n_periods == 4 and est.period == PERIOD and est.fs is None
    np.testing.assert_allclose(est.data.omega, 2 * np.pi * ODD_BINS / PERIOD, rtol=1e-15)
    rel = np.abs(est.data.response / true_response(ODD_BINS) - 1)
    assert rel.max() <= 1e-10, rel.max()
    assert np.all(np.isfinite(est.variance)) and est.variance.shape == ODD_BINS.shape
    np.testing.assert_allclose(est.coherence, 1.0, atol=1e-10)
    assert est.data.weights is not None
    assert np.isclose(est.data.weights.mean(), 1.0)


def test_fs_scales_omega_to_rad_per_s():
    u, y = simulate(3)
    est = frf_from_periodic(u, y, PERIOD, fs=1000.0, skip_periods=1)
    np.testing.assert_allclose(est.data.omega, 2 * np.pi * ODD_BINS / PERIOD * 1000.0)
    assert est.fs == 1000.0


def test_single_period_has_no_variance():
    u, y = simulate(3)
    est = frf_from_periodic(u[-PERIOD:], y[-PERIOD:], PERIOD)
    assert est.n_periods == 1
    assert est.variance is None and est.coherence is None and est.data.weights is None
    rel = np.abs(est.data.response / true_response(ODD_BINS) - 1)
    assert rel.max() <= 1e-10


def test_given_bins_are_used():
    u, y = simulate(3)
    est = frf_from_periodic(u, y, PERIOD, skip_periods=1, bins=[7, 3, 51])
    np.testing.assert_array_equal(est.bins, [3, 7, 51])
    np.testing.assert_allclose(est.data.response, true_response([3, 7, 51]), rtol=1e-10)


def test_allow_partial_drops_trailing_samples():
    u, y = simulate(4)
    u, y = u[:-100], y[:-100]
    with pytest.raises(DataError, match=r"156 samples are left over"):
        frf_from_periodic(u, y, PERIOD)
    est = frf_from_periodic(u, y, PERIOD, skip_periods=1, allow_partial=True)
    assert est.n_periods == 2
    np.testing.assert_allclose(est.data.response, true_response(ODD_BINS), rtol=1e-10)


def test_variance_matches_theory_with_output_noise():
    n_periods, sigma = 8, 0.05
    u, y = simulate(n_periods + 1)
    rng = np.random.default_rng(1)
    U = np.fft.fft(u[:PERIOD])[ODD_BINS]
    true_var = PERIOD * sigma**2 / (n_periods * np.abs(U) ** 2)  # Var(G_hat), unscaled DFT
    ratios, errors = [], []
    for _ in range(20):
        noisy = y + sigma * rng.standard_normal(y.size)
        est = frf_from_periodic(u, noisy, PERIOD, skip_periods=1)
        ratios.append(np.mean(est.variance / true_var))
        errors.append(np.abs(est.data.response - true_response(ODD_BINS)) ** 2 / true_var)
        assert np.all((est.coherence > 0) & (est.coherence <= 1))
    ratio = np.mean(ratios)
    assert 0.5 <= ratio <= 2.0, ratio
    assert 0.8 <= ratios[0] <= 1.25, ratios[0]     # 50 bins x 7 dof: ~5% spread
    # the formula itself: the actual squared error has the predicted mean
    assert 0.8 <= np.mean(errors) <= 1.25, np.mean(errors)


# --------------------------------------------------------------------------- stepped sine

def test_stepped_sine_recovers_filter_response():
    fs, n = 100.0, 1500
    freqs = np.array([0.37, 1.0, 3.3, 7.77, 12.5, 21.0, 33.3, 47.1])  # Hz, below fs/2
    t = np.arange(n) / fs
    records = []
    for k, f in enumerate(freqs):
        u = 0.7 * np.sin(2 * np.pi * f * t + 0.3 * k) + 0.1  # with an offset
        records.append((u, signal.lfilter(B, A, u)))
    order = np.arange(len(freqs))[::-1]            # unsorted input is sorted
    est = frf_stepped_sine([records[i] for i in order], fs=fs, frequencies=freqs[order],
                           n_skip=400)
    np.testing.assert_allclose(est.data.omega, 2 * np.pi * freqs)
    _, h = signal.freqz(B, A, worN=2 * np.pi * freqs / fs)
    rel = np.abs(est.data.response / h - 1)
    assert rel.max() <= 1e-8, rel.max()
    assert est.bins is None and est.variance is None and est.fs == fs


def test_stepped_sine_errors():
    fs = 100.0
    t = np.arange(300) / fs
    u = np.sin(2 * np.pi * 5.0 * t)
    with pytest.raises(DataError, match="equal lengths"):
        frf_stepped_sine([(u, u[:-1])], fs=fs, frequencies=[5.0])
    with pytest.raises(DataError, match="fewer than one cycle"):
        frf_stepped_sine([(u, u)], fs=fs, frequencies=[5.0], n_skip=290)
    with pytest.raises(DataError, match="not a sine at 7"):
        frf_stepped_sine([(u, u)], fs=fs, frequencies=[7.0])
    with pytest.raises(DataError, match=r"must be in \(0, fs/2\)"):
        frf_stepped_sine([(u, u)], fs=fs, frequencies=[60.0])
    with pytest.raises(DataError, match="repeated"):
        frf_stepped_sine([(u, u), (u, u)], fs=fs, frequencies=[5.0, 5.0])
    with pytest.raises(DataError, match="one frequency per record"):
        frf_stepped_sine([(u, u)], fs=fs, frequencies=[5.0, 6.0])
    with pytest.raises(DataError, match="must be finite"):
        frf_stepped_sine([(u, np.where(t > 1, np.nan, u))], fs=fs, frequencies=[5.0])
    with pytest.raises(DataError, match="no component"):
        frf_stepped_sine([(np.zeros(300), u)], fs=fs, frequencies=[5.0])
    with pytest.raises(OptionError, match="fs must be"):
        frf_stepped_sine([(u, u)], fs=-1.0, frequencies=[5.0])


# --------------------------------------------------------------------------- bad input

@pytest.fixture
def record():
    return simulate(3)


def test_unequal_lengths(record):
    u, y = record
    with pytest.raises(DataError, match=r"equal lengths: len\(u\)=768, len\(y\)=767"):
        frf_from_periodic(u, y[:-1], PERIOD)


def test_too_short(record):
    u, y = record
    with pytest.raises(DataError, match="too short: 100 samples < one period of 256"):
        frf_from_periodic(u[:100], y[:100], PERIOD)


def test_not_a_multiple_of_period(record):
    u, y = record
    with pytest.raises(DataError, match=r"not a multiple of period 200: 168 samples are left "
                                        r"over.*trim.*allow_partial=True"):
        frf_from_periodic(u, y, 200)


def test_skip_leaves_nothing(record):
    u, y = record
    with pytest.raises(DataError, match="skip_periods=3 leaves no period"):
        frf_from_periodic(u, y, PERIOD, skip_periods=3)


def test_not_periodic(record):
    u, y = record
    # an odd-bin multisine of period 256 is minus itself after 128 samples: the error says
    # so and gives the period (the F-16 benchmark's odd multisine read "200 %" and "raise
    # periodic_rtol", which has no command-line option)
    with pytest.raises(DataError, match=r"input is not periodic with period 128.*each period "
                       r"is minus the one before \(an odd multisine, anti-periodic at 128\): "
                       r"its period is 256, pass --period 256"):
        frf_from_periodic(u, y, 128)
    with pytest.raises(DataError, match=r"period 100.*check --period .*periodic_rtol= of "
                       r"frf_from_periodic"):
        frf_from_periodic(u[:700], y[:700], 100)
    rng = np.random.default_rng(3)
    noise = rng.standard_normal(u.size)
    with pytest.raises(DataError, match="not periodic with period 256"):
        frf_from_periodic(noise, y, PERIOD)


@pytest.mark.parametrize("value", [0.0, 2.5])
def test_no_excitation(record, value):
    _, y = record
    with pytest.raises(DataError, match="constant.*no excitation"):
        frf_from_periodic(np.full(y.size, value), y, PERIOD)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_samples(record, bad):
    u, y = record
    y = y.copy()
    y[300] = bad
    with pytest.raises(DataError, match=r"y must be finite: y\[300\]"):
        frf_from_periodic(u, y, PERIOD)
    with pytest.raises(DataError, match=r"u must be finite: u\[300\]"):
        frf_from_periodic(y, u, PERIOD)


@pytest.mark.parametrize("period, message", [(256.5, "integer"), (0, ">= 2"), (-4, ">= 2"),
                                             ("256", "integer"), (True, "integer")])
def test_bad_period(record, period, message):
    u, y = record
    with pytest.raises(DataError, match=f"period must be.*{message}"):
        frf_from_periodic(u, y, period)


def test_integral_float_period_is_accepted(record):
    u, y = record
    assert frf_from_periodic(u, y, 256.0, skip_periods=1).period == 256


@pytest.mark.parametrize("bins, message", [([0, 3], "out of range"), ([129], "out of range"),
                                           ([3, 3], "duplicates"), ([2.5], "integer"),
                                           ([2], "not excited")])
def test_bad_bins(record, bins, message):
    u, y = record
    with pytest.raises(DataError, match=message):
        frf_from_periodic(u, y, PERIOD, bins=bins)


@pytest.mark.parametrize("kwargs, message", [({"fs": 0.0}, "fs must be"),
                                             ({"skip_periods": -1}, "skip_periods"),
                                             ({"threshold": 0.0}, "threshold"),
                                             ({"periodic_rtol": -1}, "periodic_rtol")])
def test_bad_options(record, kwargs, message):
    u, y = record
    with pytest.raises(OptionError, match=message):
        frf_from_periodic(u, y, PERIOD, **kwargs)


def test_mimo_and_complex_rejected(record):
    u, y = record
    with pytest.raises(DataError, match="one-dimensional"):
        frf_from_periodic(np.stack([u, u]), y, PERIOD)
    with pytest.raises(DataError, match="complex"):
        frf_from_periodic(u + 1j, y, PERIOD)


def test_result_is_frozen(record):
    u, y = record
    est = frf_from_periodic(u, y, PERIOD, skip_periods=1)
    with pytest.raises(AttributeError):
        est.period = 3
    with pytest.raises(ValueError):
        est.bins[0] = 5


# --------------------------------------------------------------------------- loaders

def test_load_records_csv_roundtrip(tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text("# a comment\nU , Y\n1.5,2\n-3,4e-3\n")
    u, y = load_records_csv(path)
    np.testing.assert_array_equal(u, [1.5, -3.0])
    np.testing.assert_array_equal(y, [2.0, 4e-3])


@pytest.mark.parametrize("text, message", [
    ("", "is empty"),
    ("a,b\n1,2\n", "unrecognised header"),
    ("u,y\n", "no data rows"),
    ("u,y\n1,2,3\n", "line 2: expected 2 columns"),
    ("u,y\n1,2\nx,2\n", "line 3, column 'u': 'x' is not a number"),
    ("u,y\n1,nan\n", "line 2, column 'y': 'nan' is not finite"),
])
def test_load_records_csv_errors(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=message):
        load_records_csv(path)


def test_load_missing_file(tmp_path):
    with pytest.raises(DataError, match="not found"):
        load_records_csv(tmp_path / "nope.csv")
    with pytest.raises(DataError, match="directory"):
        load_daisy(tmp_path)


def test_load_daisy(tmp_path):
    path = tmp_path / "x.dat"
    path.write_text("  1.0e-01\t 2.0\n\n  3 4\n")
    u, y = load_daisy(path)
    np.testing.assert_array_equal(u, [0.1, 3.0])
    np.testing.assert_array_equal(y, [2.0, 4.0])
    path.write_text("1 2\n3 4 5\n")
    with pytest.raises(DataError, match="line 2: 3 columns, expected 2"):
        load_daisy(path)
    path.write_text("1\n")
    with pytest.raises(DataError, match="1 column"):
        load_daisy(path)
    path.write_text("1 zz\n")
    with pytest.raises(DataError, match="'zz' is not a number"):
        load_daisy(path)


# --------------------------------------------------------------------------- robot arm

def test_robot_arm():
    est = robot_arm()
    assert est.period == 1024 and est.n_periods == 1     # one period: no shorter one repeats
    np.testing.assert_array_equal(est.bins, np.arange(1, 202, 2))  # odd bins, band edge 201
    assert est.fs is None and est.variance is None
    np.testing.assert_allclose(est.data.omega, 2 * np.pi * est.bins / 1024)
    assert np.all(np.isfinite(est.data.response)) and np.all(est.data.response != 0)
    mag = np.abs(est.data.response)
    peaks = est.bins[1:-1][(mag[1:-1] > mag[:-2]) & (mag[1:-1] > mag[2:])]
    assert {59, 129} <= set(peaks.tolist())               # the arm's two resonances


def test_robot_arm_is_not_periodic_over_half_the_record():
    u, y = robot_arm_record()
    with pytest.raises(DataError, match="not periodic with period 512"):
        frf_from_periodic(u, y, 512)
    # anti-periodic instead: only odd bins are excited
    assert np.linalg.norm(u[:512] + u[512:]) < 0.1 * np.linalg.norm(u)


def robot_arm_record():
    from freqid_casadi.experiment import _find_robot_arm
    return load_daisy(_find_robot_arm())


def test_robot_arm_env_and_missing(tmp_path, monkeypatch):
    monkeypatch.setenv("FREQID_SHARED", str(tmp_path))
    with pytest.raises(DataError, match="FREQID_SHARED"):
        robot_arm()
    monkeypatch.delenv("FREQID_SHARED")
    monkeypatch.chdir(tmp_path)          # no ../shared: the copy shipped in the package
    assert robot_arm().period == 1024
    assert dataset_path("robot_arm.dat").endswith(os.path.join("datasets", "robot_arm.dat"))
    with pytest.raises(DataError, match="data set 'nope.dat' is missing from the installed"):
        dataset_path("nope.dat")


def test_unexcited_bin_is_a_data_error_not_a_huge_gain():
    u1 = multisine()
    u = np.tile(u1, 3)
    y = signal.lfilter(B, A, u)
    with pytest.raises(DataError, match=r"input has no power at bin 2 in period #1 \(\|U\|\^2 is "
                       r".* of the strongest bin, below 1e-12\): that bin is not excited"):
        frf_from_periodic(u, y, PERIOD, bins=[1, 2, 3])


# --------------------------------------------------------------------------- Welch H1/H2
FS = 1000.0
# 2nd-order resonant low-pass at 50 Hz, damping 0.1 (bilinear transform of the analog one)
B2, A2 = signal.bilinear([(2 * np.pi * 50) ** 2],
                         [1, 2 * 0.1 * 2 * np.pi * 50, (2 * np.pi * 50) ** 2], FS)


def _truth(omega):
    return signal.freqz(B2, A2, worN=omega / FS)[1]


def _excitation(kind, n, rng):
    if kind == "noise":
        return rng.standard_normal(n)
    t = np.arange(n) / FS
    return signal.chirp(t, 1.0, t[-1], 200.0, method="logarithmic")


@pytest.mark.parametrize("kind", ["noise", "chirp"])
def test_h1_recovers_a_known_system(kind):
    rng = np.random.default_rng(1)
    u = _excitation(kind, 2 ** 15, rng)
    y = signal.lfilter(B2, A2, u) + 0.02 * rng.standard_normal(u.size)
    est = frf_from_records(u, y, fs=FS, nperseg=1024, name=kind)
    d = est.data
    assert isinstance(est, FrfEstimate) and est.estimator == "h1" and d.name == kind
    assert est.nperseg == 1024 and est.n_averages == 63 and d.omega[0] > 0   # no DC bin
    np.testing.assert_allclose(d.omega, 2 * np.pi * est.bins * FS / 1024)
    band = (est.coherence > 0.99) & (d.omega < 2 * np.pi * 150)
    assert band.sum() > 50
    err = np.abs(d.response[band] / _truth(d.omega[band]) - 1)
    # A chirp is not stationary: the transient carried from one segment into the next biases
    # H1 near the lightly damped resonance (measured 0.069 at 49.8 Hz with coherence 0.991);
    # random noise gives only the random error.
    assert err.max() < {"noise": 0.03, "chirp": 0.08}[kind], err.max()
    assert np.median(err) < {"noise": 0.01, "chirp": 0.01}[kind], np.median(err)
    assert np.isclose(d.weights.mean(), 1.0)
    assert np.corrcoef(d.weights, est.coherence)[0, 1] > 0     # weights grow with coherence


def test_h1_h2_bias_under_output_and_input_noise():
    rng = np.random.default_rng(2)
    u = rng.standard_normal(2 ** 15)
    y = signal.lfilter(B2, A2, u)
    band = slice(5, 60)                                 # 5..60 bins of 1024: 5-60 Hz
    y_noisy = y + 0.3 * rng.standard_normal(u.size)     # noise on the output
    u_noisy = u + 0.3 * rng.standard_normal(u.size)     # noise on the input
    ratio = {}
    for label, (uu, yy) in {"out": (u, y_noisy), "in": (u_noisy, y)}.items():
        for est_name in ("h1", "h2"):
            e = frf_from_records(uu, yy, fs=FS, nperseg=1024, estimator=est_name)
            h = _truth(e.data.omega)[band]
            r = np.abs(e.data.response[band] / h)
            if (label, est_name) == ("out", "h2"):
                r = r / (1 + 0.09 / np.abs(h) ** 2)     # theory: |H2| = |H| (1 + s^2/|H|^2)
            ratio[label, est_name] = float(np.median(r))
    # Bendat & Piersol §9.2: H1 is unbiased by output noise, H2 by input noise; the other
    # one is biased by the factor 1/gamma^2 (H2 up) or gamma^2 (H1 down). Noise variance
    # s^2 = 0.09 against a unit-variance white input.
    assert ratio["out", "h1"] == pytest.approx(1, abs=0.02)
    assert ratio["out", "h2"] == pytest.approx(1, abs=0.02)       # biased as theory says
    assert ratio["in", "h2"] == pytest.approx(1, abs=0.02)
    assert ratio["in", "h1"] == pytest.approx(1 / 1.09, abs=0.02)   # |H1| = |H| / (1 + s^2)


def test_variance_matches_the_spread_over_repeated_experiments():
    rng = np.random.default_rng(3)
    rel, pred = [], []
    for _ in range(30):
        u = rng.standard_normal(8192)
        y = signal.lfilter(B2, A2, u) + 0.5 * rng.standard_normal(u.size)
        e = frf_from_records(u, y, fs=FS, nperseg=512)
        h = _truth(e.data.omega)
        rel.append(np.abs(e.data.response - h) ** 2 / np.abs(h) ** 2)
        pred.append(e.variance / np.abs(e.data.response) ** 2)
    band = slice(2, 60)
    measured = np.mean(np.array(rel)[:, band])
    predicted = np.mean(np.array(pred)[:, band])
    assert 0.7 < measured / predicted < 1.6, (measured, predicted)


def test_min_coherence_selects_the_band():
    rng = np.random.default_rng(4)
    u = rng.standard_normal(2 ** 14)
    y = signal.lfilter(B2, A2, u) + 0.05 * rng.standard_normal(u.size)
    full = frf_from_records(u, y, fs=FS, nperseg=512)
    sel = frf_from_records(u, y, fs=FS, nperseg=512, min_coherence=0.9)
    assert np.all(sel.coherence >= 0.9) and 0 < sel.data.n_points < full.data.n_points
    np.testing.assert_array_equal(sel.data.omega, full.data.omega[full.coherence >= 0.9])
    with pytest.raises(DataError, match=r"no frequency has coherence >= 0\.9 \(highest"):
        frf_from_records(u, rng.standard_normal(u.size), fs=FS, nperseg=512, min_coherence=0.9)


@pytest.mark.parametrize("kw, exc, match", [
    ({"estimator": "h3"}, OptionError, r"unknown estimator 'h3'; choose one of h1, h2"),
    ({"nperseg": 10 ** 6}, OptionError, r"nperseg=1000000 is longer than the records"),
    ({"nperseg": 4}, OptionError, r"nperseg must be >= 8"),
    ({"nperseg": 64, "noverlap": 64}, OptionError, r"noverlap=64 must be < nperseg=64"),
    ({"min_coherence": 1.5}, OptionError, r"min_coherence must be a number in \[0, 1\)"),
    ({"window": "nosuch"}, OptionError, r"window='nosuch' is not a scipy.signal window"),
    ({"detrend": "cubic"}, OptionError, r"detrend must be 'constant', 'linear' or False"),
    ({"fs": 0.0}, OptionError, r"fs must be a finite sampling frequency > 0 in Hz"),
    ({"fs": 1e308}, OptionError, r"fs=1e\+308 Hz is too large: omega up to pi\*fs rad/s "
                                 "overflows"),
])
def test_welch_options(kw, exc, match):
    rng = np.random.default_rng(5)
    u = rng.standard_normal(4096)
    y = signal.lfilter(B2, A2, u)
    args = {"fs": FS, "nperseg": 256, **kw}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(exc, match=match):
            frf_from_records(u, y, **args)


def test_welch_without_fs_is_in_rad_per_sample():
    # as frf_from_periodic without fs: the same estimate as at fs = 1 Hz, its axis in
    # rad/sample
    rng = np.random.default_rng(5)
    u = rng.standard_normal(4096)
    y = signal.lfilter(B2, A2, u)
    est = frf_from_records(u, y, fs=None, nperseg=256)
    one = frf_from_records(u, y, fs=1.0, nperseg=256)
    assert est.data.unit == "rad/sample" and est.fs is None
    np.testing.assert_array_equal(est.data.omega, one.data.omega)
    np.testing.assert_array_equal(est.data.response, one.data.response)


def test_welch_bad_records_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(DataError, match="input u is constant"):
            frf_from_records(np.ones(1024), np.arange(1024.0), fs=FS)
        big = np.random.default_rng(6).standard_normal(2048) * 1e300
        assert np.allclose(frf_from_records(big, big, fs=FS, nperseg=256).data.response, 1)


# --------------------------------------------------------------------------- DAQ records

@pytest.fixture(scope="module")
def actuator():
    return actuator_records()


def test_actuator_records(actuator):
    assert actuator.fs == 1000.0 and actuator.n_samples == 61500
    assert list(actuator.channels) == ["CHANNEL0", "CHANNEL1", "CHANNEL2"]
    assert actuator.events == ((0, "DAQ Start"), (61499, "DAQ Pause, DAQ Stop"))
    assert actuator.channels["CHANNEL0"][:2].tolist() == [-0.0209, -0.0221]
    assert actuator.channels["CHANNEL2"][-1] == -0.0204


def test_actuator_h1_end_to_end(actuator):
    """Raw records -> H1: coherence > 0.95 over 0.12-19.5 Hz, |H| ~ 1 at low frequency and a
    phase lag that grows with frequency (a lag plus a delay of a few ms)."""
    u = 10 * actuator.channels["CHANNEL2"]          # commanded displacement, mm
    y = 10 * actuator.channels["CHANNEL0"]          # measured displacement, mm
    est = frf_from_records(u, y, fs=actuator.fs, nperseg=8192, name="actuator")
    f = est.data.omega / (2 * np.pi)
    band = (f >= 0.12) & (f <= 19.5)
    assert band.sum() == 159 and est.n_averages == 14
    assert est.coherence[band].min() > 0.95
    h = est.data.response[band]
    assert 0.98 < abs(h[3]) < 1.01                   # 0.49 Hz
    phase = np.unwrap(np.angle(h))
    assert np.degrees(phase[-1]) == pytest.approx(-98.7, abs=2)          # 19.04 Hz
    assert np.all(np.diff(phase[::8]) < 0)           # lag grows with frequency
    assert abs(h[-1]) == pytest.approx(0.353, abs=0.01)


@pytest.mark.parametrize("text, match", [
    ("Version: 2\n", r"line 1: expected 'Header Size: N'"),
    ("Header Size: 3\nSampling Rate: 1000\nA, B, C\n", r"line 3: expected 'Sample Number"),
    ("Header Size: 3\nSampling Rate: x\nN, T, CHANNEL0\n1, t, 1\n2, t, 2\n",
     r"no valid 'Sampling Rate: HZ'"),
    ("Header Size: 3\nSampling Rate: 10\nN, T, CHANNEL0\n1, t, 1\n2, t, 1_0\n",
     r"line 5, column 'CHANNEL0': '1_0' is not a number"),
    ("Header Size: 4\nSampling Rate: 10\nSample Count: 3\nN, T, CHANNEL0\n1, t, 1\n2, t, 2\n",
     r"Sample Count: 3, the file holds 2 samples"),
    ("Header Size: 3\nSampling Rate: 10\nN, T, CHANNEL0, CHANNEL1\n1, t, 1\n",
     r"line 4: expected sample number, time stamp and 2 channels, got 3 fields"),
])
def test_daq_errors(tmp_path, text, match):
    path = tmp_path / "daq.txt"
    path.write_text(text)
    with pytest.raises(DataError, match=match):
        load_daq_records(path)


def test_records_readers_refuse_devices_and_bom_is_fine(tmp_path):
    with pytest.raises(DataError, match="character device, not a regular file"):
        load_records_csv("/dev/zero")
    path = tmp_path / "r.csv"
    path.write_bytes("\ufeffu,y\n1,2\n3,4\n".encode())
    u, y = load_records_csv(path)
    assert u.tolist() == [1.0, 3.0] and y.tolist() == [2.0, 4.0]


@pytest.mark.parametrize("scale, rtol", [(1e-300, 1e-9), (1e300, 1e-9),
                                         (1e-320, 0.02)])   # subnormal: the data keep ~8 bits
def test_estimators_are_scale_free_and_quiet(scale, rtol):
    """Records in any units (1e-320 to 1e300) give the same FRF, with no RuntimeWarning:
    the spectra are taken of records scaled by powers of two."""
    rng = np.random.default_rng(7)
    u = np.tile(rng.standard_normal(64), 4)
    y = 3 * u + 1e-3 * rng.standard_normal(u.size)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for f in (lambda a, b: frf_from_periodic(a, b, 64),
                  lambda a, b: frf_from_records(a, b, fs=10.0, nperseg=64)):
            ref, scaled = f(u, y), f(u * scale, y * scale)
            np.testing.assert_allclose(scaled.data.response, ref.data.response, rtol=rtol)
            if rtol < 1e-3:
                np.testing.assert_allclose(scaled.variance, ref.variance, rtol=1e-6)
        with pytest.raises(DataError, match=r"differ by a factor 2\^1995: the response is "
                           r"outside the floating-point range"):
            frf_from_records(u * 1e-300, y * 1e300, fs=10.0)

"""The last three hostile inputs of issue 27: a frequency axis scaled by 1e150 through
``freqid fit`` (plots included), uniform weights of any size (1e-320 too), and records near
the largest float through ``freqid frf``."""

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.core.model import RationalDelayModel, Structure
from freqid_casadi.errors import DataError
from freqid_casadi.experiment import periodic
from freqid_casadi.io.loaders import save_csv

ROOT = Path(__file__).resolve().parents[1]
W = np.logspace(-1, 2, 40)
MODEL = RationalDelayModel(Structure(1), [0.01, 2.0, 1.0, 0.3, 5.0, 1.0, 0.05, 3.0])
R = MODEL.frequency_response(W)


def run(argv, cwd, timeout=180):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["MPLBACKEND"] = "Agg"
    return subprocess.run([sys.executable, "-m", "freqid_casadi", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def one_error(err, *needles):
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "internal error" not in err and "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])


# ------------------------------------------------------------------ omega scaled by 1e150


def test_a_model_at_1e150_rad_per_s_evaluates_without_overflow():
    # before: |den|^2 of a section at 1e152 rad/s (1e608) overflowed to inf, the response
    # to 0 / NaN, and the report's plots failed on NaN axis limits
    theta = MODEL.beta.copy()
    theta[0] /= 1e150                                   # delay in s
    theta[[4, 7]] *= 1e150                              # wn, wd in rad/s
    big = RationalDelayModel(Structure(1), theta)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = big.frequency_response(W * 1e150)
    assert np.all(np.isfinite(g))
    np.testing.assert_allclose(g, R, rtol=1e-13)


def test_freqid_fit_of_omega_scaled_by_1e150_writes_a_finite_report(tmp_path):
    save_csv(fc.FrequencyData(W * 1e150, R, "scaled"), tmp_path / "big.csv")
    proc = run(["fit", "big.csv", "--sections", "1", "--out", "rep"], tmp_path)
    assert "Traceback" not in proc.stderr and "warning" not in proc.stderr.lower(), proc.stderr
    if proc.returncode != 0:                            # a typed error, nothing written
        assert proc.returncode == 2
        one_error(proc.stderr)
        assert not (tmp_path / "rep").exists()
        return
    s = json.loads((tmp_path / "rep" / "summary.json").read_text())
    assert np.isfinite(s["max_rel_error"]) and s["max_rel_error"] < 1e-8   # scale free
    for name in ("bode.png", "rel_error.png", "pole_zero.png", "rel_error.csv"):
        assert (tmp_path / "rep" / name).stat().st_size > 0
    errs = np.loadtxt(tmp_path / "rep" / "rel_error.csv", delimiter=",", skiprows=1)
    assert np.all(np.isfinite(errs))


# ------------------------------------------------------------------ uniform weights


@pytest.mark.parametrize("scale", [1e-320, 3.0, 1e300])
def test_uniform_weights_of_any_size_fit_exactly_like_none(scale):
    # before: 1e-320 (its power-of-two scale clamped at 2^-1000, so the solvers saw weights
    # of 1e-19) ended at max rel. error 5.8e-8 in 11 iterations against 2.3e-14 in 29
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = fc.fit(W, R, n_sections=1)
        weighted = fc.fit(W, R, n_sections=1, weights=np.full(W.size, scale))
    assert weighted.max_rel_error == plain.max_rel_error
    assert weighted.nit == plain.nit
    np.testing.assert_array_equal(weighted.model.beta, plain.model.beta)
    assert weighted.data.weights[0] == scale            # the user's weights are kept


def test_normalised_weights_keep_the_ratios():
    from freqid_casadi.core.scaling import normalised_weights

    assert normalised_weights(np.full(5, 1e-320)) is None
    w = np.array([1e-320, 2e-320, 4e-320, 0.0])
    n = normalised_weights(w)
    assert 2 ** -0.5 <= n.mean() <= 2 ** 0.5
    np.testing.assert_allclose(n[:3] / n[0], [1.0, 2.0, 4.0], rtol=1e-2)   # subnormal bits
    assert n[3] == 0.0


# ------------------------------------------------------------------ records near 1e307


def _records(path, top, n=4096, seed=0):
    """u, y of white noise through y[k] = 0.3 u[k-1] + 0.2 u[k-2] + 0.1 u[k-3], scaled so
    that max |u| = ``top``."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n)
    y = np.convolve(u, [0.0, 0.3, 0.2, 0.1])[:n]
    k = top / np.max(np.abs(u))
    Path(path).write_text("u,y\n" + "".join(f"{float(a * k)!r},{float(b * k)!r}\n"
                                             for a, b in zip(u, y)))


@pytest.mark.parametrize("top", [1e307, 1.7e308])
def test_freqid_frf_of_records_near_the_largest_float(tmp_path, top):
    # before: 1.7e308 "internal error (OverflowError: math range error)" (the records'
    # power-of-two scale 2^1024) and a warning from np.ptp's overflowing max - min
    _records(tmp_path / "rec.csv", top)
    proc = run(["frf", "rec.csv", "--fs", "100", "--out", "f.csv"], tmp_path)
    assert "Traceback" not in proc.stderr and "warning" not in proc.stderr.lower(), proc.stderr
    if proc.returncode != 0:
        assert proc.returncode == 2
        one_error(proc.stderr, "overflow")
        assert sorted(os.listdir(tmp_path)) == ["rec.csv"]
        return
    d = fc.load(tmp_path / "f.csv")
    z = np.exp(-1j * d.omega / 100)
    truth = 0.3 * z + 0.2 * z ** 2 + 0.1 * z ** 3       # the filter, exact
    assert np.max(np.abs(d.response - truth) / np.abs(truth)) < 0.05      # noise only


def test_an_overflowing_fft_of_a_period_is_a_data_error_and_nothing_is_written(
        tmp_path, monkeypatch):
    # the records are scaled before the FFT, so it cannot overflow; without that scaling
    # (monkeypatched away) one period of 64 samples near 1e307 sums past the largest float
    # and the estimate must say so instead of writing inf or NaN
    monkeypatch.setattr(periodic, "_normalised", lambda u, y: (u, y, 1.0))
    n = np.arange(64)
    u = 1e307 * np.cos(2 * np.pi * n / 64)
    y = 0.5 * u
    with pytest.raises(DataError, match=r"the FFT of the input record overflows .*rescale"):
        periodic.frf_from_periodic(u, y, 64)
    from freqid_casadi.cli import main

    Path(tmp_path / "rec.csv").write_text(
        "u,y\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(u, y)))
    monkeypatch.chdir(tmp_path)
    assert main(["frf", "rec.csv", "--period", "64", "--out", "f.csv"]) == 2
    assert sorted(os.listdir(tmp_path)) == ["rec.csv"]

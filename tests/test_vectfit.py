"""The one vector fitting (baselines.vectfit): 1 and 3 channels of a known rational system,
fixed poles, residues at given poles, the old names that call it, and bad input."""

import numpy as np
import pytest

from freqid_casadi import FrequencyData
from freqid_casadi.baselines._ssmodel import pole_residue_ss
from freqid_casadi.baselines import (VectorFit, fit_residues, initial_poles, vectfit,
                                     vector_fitting)
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.modal._start import lsfd_residues, shared_vector_fitting

OMEGA = np.geomspace(1.0, 100.0, 300)
S = 1j * OMEGA
#: the known system's common poles (rad/s): two lightly damped pairs and a real pole
POLES = np.array([-5.0, -0.3 + 10j, -1.0 + 40j, -0.3 - 10j, -1.0 - 40j])
#: each channel's residues at POLES (conjugate poles, conjugate residues) and constant
RESIDUES = np.array([[3.0, 1 + 0.5j, 2 + 1j, 1 - 0.5j, 2 - 1j],
                     [4.0, 1 + 0.0j, 1 + 1j, 1 - 0.0j, 1 - 1j],
                     [5.0, 1 - 0.5j, 0 + 1j, 1 + 0.5j, 0 - 1j]])
CONSTANTS = np.array([0.1, 0.2, 0.3])


def _response(poles, residues, constants):
    return constants[:, None] + np.sum(residues[:, :, None] / (S - poles[:, None]), axis=1)


PHI = _response(POLES, RESIDUES, CONSTANTS)             # (3, 300)


def _sorted(p):
    return np.sort_complex(np.asarray(p, complex))


@pytest.mark.parametrize("channels", [1, 3])
def test_recovers_known_system(channels):
    """Poles, residues and constants of 1 and 3 channels. Measured (default and Prescott
    OpenBLAS kernels): poles 2e-15 relative, residues 8e-15, response 4e-14 relative; the
    bounds 1e-10 leave a factor > 1000."""
    phi = PHI[:channels]
    fit = vectfit(OMEGA, phi if channels > 1 else phi[0], 5)
    assert isinstance(fit, VectorFit) and fit.n_relocated == 5
    assert fit.residues.shape == (channels, 5) and fit.constants.shape == (channels,)
    p = fit.poles
    assert np.max(np.abs(_sorted(p) - _sorted(POLES)) / np.abs(_sorted(POLES))) < 1e-10
    # the residue of each true pole: that of the fitted pole nearest to it
    near = [int(np.argmin(np.abs(p - q))) for q in POLES]
    assert np.max(np.abs(fit.residues[:, near] - RESIDUES[:channels])) < 1e-10
    assert np.max(np.abs(fit.constants - CONSTANTS[:channels])) < 1e-10
    assert np.max(np.abs(fit.response(OMEGA) / phi - 1)) < 1e-10


def test_one_channel_is_vector_fitting():
    """baselines.vector_fitting is vectfit of one channel: the same realisation, bitwise."""
    data = FrequencyData(OMEGA, PHI[1])
    model = vector_fitting(data, 5, n_iter=4, enforce_stable_poles=True)
    fit = vectfit(OMEGA, PHI[1], 5, n_iter=4, stable=True)
    p, r = fit.poles, fit.residues[0]
    real, upper = p.imag == 0, p.imag > 0
    same = pole_residue_ss(p[real].real, r[real].real, p[upper], r[upper], fit.constants[0],
                           "vector-fitting")
    for name in "ABCD":
        assert np.array_equal(getattr(model, name), getattr(same, name)), name


def test_many_channels_agree_with_one():
    """Three copies of one channel (the eliminated problem) give that channel's poles
    (the stacked problem): measured 1e-15 relative, bound 1e-10."""
    one = vectfit(OMEGA, PHI[2], 5)
    three = vectfit(OMEGA, np.tile(PHI[2], (3, 1)), 5)
    assert np.max(np.abs(_sorted(one.poles) - _sorted(three.poles))
                  / np.abs(_sorted(one.poles))) < 1e-10


def test_fixed_poles_are_kept_and_the_others_relocated():
    """With the pairs fixed, the iterations find the real pole; the fixed ones come last."""
    fit = vectfit(OMEGA, PHI, 1, fixed=POLES[1:], n_iter=10)
    assert fit.n_relocated == 1 and fit.poles.size == 5
    assert abs(fit.poles[0] - POLES[0]) < 1e-9 * 5
    assert np.array_equal(_sorted(fit.poles[1:]), _sorted(POLES[1:]))
    assert np.max(np.abs(fit.response(OMEGA) / PHI - 1)) < 1e-10


def test_fit_residues_in_the_callers_order():
    res, const = fit_residues(OMEGA, PHI, POLES)
    assert np.max(np.abs(res - RESIDUES)) < 1e-10
    assert np.max(np.abs(const - CONSTANTS)) < 1e-10
    order = [3, 0, 4, 2, 1]
    res2, _ = fit_residues(OMEGA, PHI, POLES[order])
    assert np.max(np.abs(res2 - RESIDUES[:, order])) < 1e-10


def test_initial_poles_cover_the_band():
    p = initial_poles(OMEGA, 5)
    assert p.size == 5 and p[0] == -np.exp(np.mean(np.log(OMEGA)))
    assert np.isclose(p[1].imag, OMEGA[0]) and np.isclose(p[2].imag, OMEGA[-1])
    assert np.array_equal(p[3:], np.conj(p[1:3]))


def test_old_modal_names_call_it():
    poles, residues, consts = shared_vector_fitting(OMEGA, PHI, 5, None, 10, constant=True)
    assert poles.shape == (5,) and residues.shape == (3, 5) and consts.shape == (3,)
    assert np.max(np.abs(_sorted(poles) - _sorted(POLES)) / np.abs(_sorted(POLES))) < 1e-10
    poles2, residues2 = shared_vector_fitting(OMEGA, PHI - CONSTANTS[:, None], 5)
    assert np.max(np.abs(_sorted(poles2) - _sorted(POLES)) / np.abs(_sorted(POLES))) < 1e-10
    res, const = lsfd_residues(OMEGA, PHI, POLES)
    assert np.max(np.abs(res - RESIDUES)) < 1e-10 and np.allclose(const, CONSTANTS)


@pytest.mark.parametrize("call, error, match", [
    (lambda: vectfit(OMEGA[::-1], PHI, 4), DataError, "strictly increasing"),
    (lambda: vectfit(OMEGA, PHI[:, :10], 4), DataError, r"shape \(M,\) or \(C, M\)"),
    (lambda: vectfit(OMEGA, np.zeros(300), 4), DataError, "nonzero"),
    (lambda: vectfit(OMEGA[:4], PHI[:, :4], 4), DataError, "too few points"),
    (lambda: vectfit(OMEGA, PHI, 0), OptionError, "n_poles must be >= 1"),
    (lambda: vectfit(OMEGA, PHI, 4, n_iter=-1), OptionError, "n_iter must be >= 0"),
    (lambda: vectfit(OMEGA, PHI, 4, weighting="abs"), OptionError, "weighting"),
    (lambda: vectfit(OMEGA, PHI, 2, initial=[-1 + 2j, -1 + 2j]), OptionError,
     "complete conjugate pairs"),
    (lambda: vectfit(OMEGA, PHI, 3, initial=[-1 + 2j, -1 - 2j]), OptionError,
     "n_poles = 3"),
    (lambda: vectfit(OMEGA, PHI, 2, weights=np.ones(7)), DataError, "weights"),
])
def test_bad_input_is_a_typed_error(call, error, match):
    with pytest.raises(error, match=match):
        call()


@pytest.mark.parametrize("channels", [1, 3])
def test_blockwise_reduction_solves_the_same_problems(channels, monkeypatch):
    """Above ``_TALL_POINTS`` frequencies each least-squares problem is reduced block by
    block to its R factor. Forced here on the 300 points in blocks of 64 (the last one
    short), with fixed poles too: poles, residues and constants agree with the direct
    solution. Measured 3e-15 (poles), 3e-15 (residues) relative; bound 1e-10."""
    import importlib

    vf = importlib.import_module("freqid_casadi.baselines.vectfit")
    phi = PHI[:channels]
    direct = [vectfit(OMEGA, phi, 5), vectfit(OMEGA, phi, 1, fixed=POLES[1:])]
    monkeypatch.setattr(vf, "_TALL_POINTS", 0)
    monkeypatch.setattr(vf, "_CHUNK_POINTS", 64)
    blocks = [vectfit(OMEGA, phi, 5), vectfit(OMEGA, phi, 1, fixed=POLES[1:])]
    for a, b in zip(direct, blocks):
        assert np.max(np.abs(_sorted(a.poles) - _sorted(b.poles))
                      / np.abs(_sorted(a.poles))) < 1e-10
        assert np.max(np.abs(a.residues - b.residues)) < 1e-10 * np.max(np.abs(a.residues))
        assert np.max(np.abs(a.constants - b.constants)) < 1e-10
    res, const = fit_residues(OMEGA, phi, POLES)
    assert np.max(np.abs(res - RESIDUES[:channels])) < 1e-10
    assert np.max(np.abs(const - CONSTANTS[:channels])) < 1e-10
    res_plain, _ = fit_residues(OMEGA, phi, POLES, scaled=False)
    assert np.max(np.abs(res_plain - RESIDUES[:channels])) < 1e-10


def test_many_points_recover_the_known_system():
    """20 000 frequencies (above ``_TALL_POINTS``: the blockwise path as the fit runs it):
    the known system's poles and the response. Measured 3e-15 / 2e-14; bound 1e-10."""
    omega = np.geomspace(1.0, 100.0, 20_000)
    s = 1j * omega
    phi = CONSTANTS[0] + np.sum(RESIDUES[0][:, None] / (s - POLES[:, None]), axis=0)
    fit = vectfit(omega, phi, 5)
    assert np.max(np.abs(_sorted(fit.poles) - _sorted(POLES)) / np.abs(POLES).min()) < 1e-10
    assert np.max(np.abs(fit.response(omega)[0] / phi - 1)) < 1e-10


def test_lstsq_is_scipys_to_the_last_bit():
    """The relocations' least squares call LAPACK's dgelsd directly (workspace sizes kept
    per shape), or from 256 rows its QR path in three calls: the same numbers as
    scipy.linalg.lstsq, tall, wide, rank-deficient and badly scaled, with and without
    overwriting (up to 44 columns: dgeqrf's and dormqr's blocked code from 32); non-finite
    input is a ValueError, as there."""
    import importlib

    import scipy.linalg

    lstsq = importlib.import_module("freqid_casadi.baselines.vectfit")._lstsq
    rng = np.random.default_rng(7)
    for i in range(400):
        n = int(rng.integers(1, 30 if i < 300 else 45))
        m = int(rng.integers(1, 200) if i < 300 else rng.integers(256, 2000))  # tall: QR first
        a = rng.standard_normal((m, n)) * 10.0 ** rng.uniform(-8, 8, n)
        if n > 1 and rng.random() < 0.3:
            a[:, -1] = a[:, 0]                                  # rank-deficient
        if rng.random() < 0.3:
            a = np.asfortranarray(a)
        b = rng.standard_normal(m)
        x = lstsq(a, b)
        assert x.shape == (n,) and np.array_equal(x, scipy.linalg.lstsq(a, b)[0])
        assert np.array_equal(lstsq(np.asfortranarray(a), b.copy(), overwrite=True), x)
    with pytest.raises(ValueError, match="infs or NaNs"):
        lstsq(np.array([[np.nan, 1.0]]), np.ones(1))


@pytest.mark.parametrize("fixed, weights", [(False, False), (True, True)])
def test_one_channel_relocation_is_the_stacked_problem(fixed, weights):
    """A one-channel relocation writes ``[Re; Im]`` of ``w [Phi, fixed, 1 | -G Phi, -G]``
    and the relaxation row into one matrix: the new poles are those of the textbook
    stacked problem formed from complex blocks and solved by scipy's lstsq (columns of
    unit norm). Measured identical to the last bit here; bound 1e-12 relative."""
    import importlib

    import scipy.linalg

    vf = importlib.import_module("freqid_casadi.baselines.vectfit")
    rng = np.random.default_rng(3)
    s = 1j * OMEGA
    g = PHI[0] * (1 + 0.05 * rng.standard_normal(OMEGA.size))
    wt = 1 / np.abs(g) * (np.sqrt(rng.uniform(0.2, 1, OMEGA.size)) if weights else 1)
    rp, cp = vf._initial_split(OMEGA, 5)
    fix = vf._split(POLES[[1, 3]], "fixed") if fixed else (np.zeros(0), np.zeros(0, complex))
    got = vf._relocate(s, g[None], wt[None], rp, cp, fix, 1, True)

    basis = vf._basis(s, rp, cp)
    sig = np.hstack([basis, np.ones((s.size, 1))])
    left = np.hstack([basis] + ([vf._basis(s, *fix)] if fixed else [])
                     + [np.ones((s.size, 1))])
    block = wt[:, None] * np.hstack([left, -g[:, None] * sig])
    norm = np.linalg.norm(wt * g)
    relax = np.concatenate([np.zeros(left.shape[1]), np.sum(sig, axis=0).real])
    relax *= norm / s.size
    a = np.vstack([block.real, block.imag, relax])
    rhs = np.zeros(a.shape[0])
    rhs[-1] = norm
    scale = np.linalg.norm(a, axis=0)
    x = scipy.linalg.lstsq(a / scale, rhs)[0] / scale
    state, b = vf._state_matrices(rp, cp)
    lam = np.linalg.eigvals(state - np.outer(b, x[left.shape[1]:-1]) / x[-1])
    want = vf._split_eigs(np.where(lam.real > 0, -np.conj(lam), lam))
    for g_, w_ in zip(got, want):
        assert g_.shape == w_.shape
        assert np.all(np.abs(g_ - w_) <= 1e-12 * np.abs(w_))


def test_relocation_pieces_are_the_per_pole_formulas():
    """The basis, the state matrices and the column norms a relocation forms for all poles
    at once are, to the last bit, the one-pole-at-a-time formulas they replace
    (``1/(s - a)``; ``u + v`` and ``j u - j v`` with ``u = 1/(s - a)``, ``v = 1/(s - a*)``;
    Gustavsen's 2 x 2 blocks; numpy's norm of each column): the relocations give the
    same poles as before, whatever the pole count."""
    import importlib

    vf = importlib.import_module("freqid_casadi.baselines.vectfit")
    rng = np.random.default_rng(11)
    for n_real, n_pairs in [(0, 1), (1, 0), (1, 3), (2, 6), (0, 12)]:
        rp = -rng.uniform(0.1, 50, n_real)
        cp = -rng.uniform(0.01, 5, n_pairs) + 1j * rng.uniform(1, 90, n_pairs)
        cols = [1.0 / (S - a) for a in rp]
        rows_a = np.zeros((n_real + 2 * n_pairs,) * 2)
        b = np.zeros(n_real + 2 * n_pairs)
        for k, a in enumerate(rp):
            rows_a[k, k], b[k] = a, 1.0
        for j, a in enumerate(cp):
            u, v = 1.0 / (S - a), 1.0 / (S - np.conj(a))
            cols += [u + v, 1j * u - 1j * v]
            k = n_real + 2 * j
            rows_a[k:k + 2, k:k + 2] = [[a.real, a.imag], [-a.imag, a.real]]
            b[k] = 2.0
        basis = vf._basis(S, rp, cp)
        assert np.array_equal(basis, np.stack(cols, axis=1))
        state, b_got = vf._state_matrices(rp, cp)
        assert np.array_equal(state, rows_a) and np.array_equal(b_got, b)
        real = np.vstack([basis.real, basis.imag]) * 10.0 ** rng.uniform(-5, 5)
        assert np.array_equal(vf._column_norms(real), np.linalg.norm(real, axis=0))

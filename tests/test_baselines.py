"""Tests of freqid_casadi.baselines: each baseline recovers a system that generated its data,
or matches a closed form. Test data are generated inline (no systems.py)."""

import subprocess
import sys
from math import comb

import numpy as np
import pytest
import scipy.integrate

from freqid_casadi import baselines
from freqid_casadi.baselines import (StateSpaceModel, aaa, balanced_truncation,
                                     balanced_truncation_error_bound, continued_fraction_sqrt,
                                     count_rhp, feedthrough_from_data, fourier,
                                     hankel_singular_values, modal_model, moheimani_kopt,
                                     newton_sqrt, newton_sqrt_polynomials, subspace,
                                     vector_fitting)
from freqid_casadi.baselines._ssmodel import bilinear_c2d, bilinear_d2c
from freqid_casadi.core.data import FrequencyData
from freqid_casadi.errors import DataError, OptionError, StructureError
from freqid_casadi.core.model import RationalDelayModel, Structure

# ----------------------------------------------------------------------------- test systems


def _tf_response(num, den, s):
    return np.polyval(num, s) / np.polyval(den, s)


# 4th order, stable, minimum phase, strictly proper:
# (2s^2 + s + 8)(s + 3) / ((s^2 + 0.6s + 4.09)(s^2 + 2s + 1.25))
NUM4 = np.polymul([2.0, 1.0, 8.0], [1.0, 3.0])
DEN4 = np.polymul([1.0, 0.6, 4.09], [1.0, 2.0, 1.25])
POLES4 = np.sort_complex(np.array([-0.3 + 2j, -0.3 - 2j, -1 + 0.5j, -1 - 0.5j]))

# 3rd order, biproper, right-half-plane zero at s = 2:
# (s - 2)(s^2 + 0.5s + 9) / ((s + 1)(s^2 + 0.3s + 4))
NUM_NMP = np.polymul([1.0, -2.0], [1.0, 0.5, 9.0])
DEN_NMP = np.polymul([1.0, 1.0], [1.0, 0.3, 4.0])

OMEGA = np.logspace(-2, 2, 200)


def _g4(omega):
    return _tf_response(NUM4, DEN4, 1j * np.asarray(omega, float))


def _data4():
    return FrequencyData(OMEGA, _g4(OMEGA), "G4")


def _max_rel(model, omega, response):
    return float(np.max(np.abs(model.frequency_response(omega) / response - 1.0)))


# Moheimani's simply-supported beam (SPEC §4, seed 003 §3)
BEAM_L, BEAM_R1, BEAM_R2, BEAM_RHOA, BEAM_EI = 1.3, 0.075, 0.075, 0.6265, 5.329
BEAM_N_MODES, BEAM_N_KEPT, BEAM_OMEGA_C = 30, 2, 100.0


def _beam_modes():
    i = np.arange(1, BEAM_N_MODES + 1)
    omega_i = (i * np.pi / BEAM_L) ** 2 * np.sqrt(BEAM_EI / BEAM_RHOA)

    def phi(r):
        return np.sqrt(2.0 / (BEAM_RHOA * BEAM_L)) * np.sin(i * np.pi * r / BEAM_L)

    return omega_i, phi(BEAM_R1) * phi(BEAM_R2)


def _modal_sum(omega_i, F_i):
    def response(omega):                  # sum_i F_i / (s^2 + omega_i^2) at s = j omega
        w = np.asarray(omega, float)
        return np.sum(F_i / (omega_i ** 2 - w[..., None] ** 2), axis=-1).astype(complex)
    return response


# ----------------------------------------------------------------------------- StateSpaceModel


def test_state_space_model_matches_transfer_function():
    A = np.array([[0.0, 1.0], [-4.0, -0.4]])
    m = StateSpaceModel(A, [0.0, 1.0], [3.0, 1.0], 0.5, delay=0.1, name="x")
    s = 1j * OMEGA
    expected = np.exp(-0.1 * s) * ((s + 3.0) / (s ** 2 + 0.4 * s + 4.0) + 0.5)
    assert np.max(np.abs(m.frequency_response(OMEGA) / expected - 1)) < 1e-13
    assert m.order == 2 and m.delay == 0.1 and m.is_stable()
    z = np.sort_complex(m.zeros())
    assert np.allclose(z, np.sort_complex(np.roots([0.5, 1.2, 5.0])), atol=1e-12)
    sys_ct = m.to_control()
    assert sys_ct.delay == 0.1 and sys_ct.nstates == 2
    assert not m.A.flags.writeable


def test_state_space_model_rejects_bad_shapes():
    with pytest.raises(StructureError, match="A must be a square"):
        StateSpaceModel(np.zeros((2, 3)), [1, 1], [1, 1], 0.0)
    with pytest.raises(StructureError, match="B must have shape"):
        StateSpaceModel(np.eye(2), [1, 1, 1], [1, 1], 0.0)
    with pytest.raises(StructureError, match="delay must be"):
        StateSpaceModel(np.eye(1), [1], [1], 0.0, delay=-1.0)


def test_bilinear_maps_are_inverse_and_exact():
    A = np.array([[-1.0, 2.0], [-3.0, -0.5]])
    B, C, D, T = np.array([[1.0], [0.5]]), np.array([[2.0, -1.0]]), 0.3, 0.4
    Ad, Bd, Cd, Dd = bilinear_c2d(A, B, C, D, T)
    theta = np.linspace(0.1, 3.0, 7)
    z = np.exp(1j * theta)
    s = (2 / T) * (z - 1) / (z + 1)
    gc = np.array([(C @ np.linalg.solve(sk * np.eye(2) - A, B))[0, 0] + D for sk in s])
    gd = np.array([(Cd @ np.linalg.solve(zk * np.eye(2) - Ad, Bd))[0, 0] + Dd for zk in z])
    assert np.max(np.abs(gd - gc)) < 1e-13
    A2, B2, C2, D2 = bilinear_d2c(Ad, Bd, Cd, Dd, T)
    assert np.allclose(A2, A, atol=1e-13) and np.allclose(B2, B, atol=1e-13)
    assert np.allclose(C2, C, atol=1e-13) and abs(D2 - D) < 1e-13


# ----------------------------------------------------------------------------- subspace


def test_subspace_recovers_fourth_order_system():
    m = subspace(_data4(), 4)
    err = _max_rel(m, OMEGA, _g4(OMEGA))
    print(f"subspace max rel error {err:.3e}")
    assert err <= 1e-8
    assert np.allclose(np.sort_complex(m.poles()), POLES4, atol=1e-8)
    assert m.delay == 0.0 and m.name == "subspace" and m.order == 4


def test_subspace_bad_input():
    with pytest.raises(DataError, match="FrequencyData"):
        subspace((OMEGA, _g4(OMEGA)), 4)
    with pytest.raises(OptionError, match="order must be >= 1"):
        subspace(_data4(), 0)
    with pytest.raises(OptionError, match="q must be >= 5"):
        subspace(_data4(), 4, q=4)


# ----------------------------------------------------------------------------- Fourier


def test_fourier_error_decreases_with_n_fft():
    errors = [_max_rel(fourier(_g4, 4, n_fft=n, T=2.0), OMEGA, _g4(OMEGA))
              for n in (64, 128, 256)]
    print("fourier max rel errors (n_fft 64, 128, 256):", ", ".join(f"{e:.3e}" for e in errors))
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] <= 1e-4


def test_fourier_from_data_interpolation_runs():
    m = fourier(_data4(), 4, n_fft=256)
    assert m.order == 4 and m.name == "fourier"
    assert _max_rel(m, OMEGA, _g4(OMEGA)) < 0.05      # limited by the interpolation only


def test_fourier_bad_input():
    with pytest.raises(OptionError, match="n_fft must be even"):
        fourier(_g4, 4, n_fft=63)
    with pytest.raises(DataError, match="callable"):
        fourier(42, 4)


# ----------------------------------------------------------------------------- 1/sqrt(s)


def test_newton_process_first_iterates_closed_form():
    num, den = newton_sqrt_polynomials(1)                 # H1 = (1 + 3x)/(3 + x)
    assert np.array_equal(num, [1.0, 3.0]) and np.array_equal(den, [3.0, 1.0])
    num, den = newton_sqrt_polynomials(2)
    assert np.array_equal(num, [1.0, 36.0, 126.0, 84.0, 9.0])
    assert np.array_equal(den, [9.0, 84.0, 126.0, 36.0, 1.0])
    for k in (1, 2, 3):                                   # num_j = C(3^k, 2j), den_j = C(3^k, 2j+1)
        m = 3 ** k
        num, den = newton_sqrt_polynomials(k)
        assert np.array_equal(num, [comb(m, 2 * j) for j in range((m + 1) // 2)])
        assert np.array_equal(den, [comb(m, 2 * j + 1) for j in range((m + 1) // 2)])


def test_newton_model_equals_polynomial_iterate():
    omega = np.logspace(-4, 4, 300)
    for k in (1, 2, 3):
        num, den = newton_sqrt_polynomials(k, x0=2.0)
        x = 1.0 / (1j * omega)
        H = np.polynomial.polynomial.polyval(x, num) / np.polynomial.polynomial.polyval(x, den)
        model = newton_sqrt(k, x0=2.0)
        assert model.order == (3 ** k - 1) // 2
        assert np.max(np.abs(model.frequency_response(omega) / H - 1)) < 1e-12
        assert model.is_stable() and model.is_minimum_phase()
    m = newton_sqrt(2, x0=2.0)                            # exact at s = 1/x0^2: H = x0
    g = (m.C @ np.linalg.solve(0.25 * np.eye(m.order) - m.A, m.B))[0, 0] + m.D
    assert abs(g - 2.0) < 1e-13
    with pytest.raises(OptionError, match="n_iter must be <= 5"):
        newton_sqrt(6)


def test_continued_fraction_interpolates_and_is_stable():
    n = 6
    model = continued_fraction_sqrt(n, omega_0=1.0, n_decades=10.0)
    x_k = 10.0 ** (10.0 * (np.arange(2 * n + 1) / (2 * n) - 0.5))
    g = np.array([(model.C @ np.linalg.solve(x * np.eye(n) - model.A, model.B))[0, 0]
                  + model.D for x in x_k])
    assert np.max(np.abs(g * np.sqrt(x_k) - 1)) < 1e-9
    assert model.order == n and model.is_stable() and model.is_minimum_phase()
    assert count_rhp(model) == (0, 0)
    omega = np.logspace(-5, 5, 500)
    err6 = np.max(np.abs(model.frequency_response(omega) * np.sqrt(1j * omega) - 1))
    err12 = np.max(np.abs(continued_fraction_sqrt(12).frequency_response(omega)
                          * np.sqrt(1j * omega) - 1))
    print(f"continued fraction max rel error on 1e-5..1e5: order 6 {err6:.3e}, "
          f"order 12 {err12:.3e}")
    assert err12 < err6 < 1.0


# ----------------------------------------------------------------------------- Moheimani


def test_moheimani_kopt_matches_numerical_integral_on_beam():
    omega_i, F_i = _beam_modes()
    assert omega_i[1] < BEAM_OMEGA_C < omega_i[2]
    k_opt = moheimani_kopt(omega_i, F_i, BEAM_N_KEPT, BEAM_OMEGA_C)
    # (a) data-based form: full 30-mode model minus the 2-mode truncation, quad on [0, wc]
    g_full = _modal_sum(omega_i, F_i)
    g_trunc = _modal_sum(omega_i[:BEAM_N_KEPT], F_i[:BEAM_N_KEPT])
    k_num = feedthrough_from_data(g_full, g_trunc, BEAM_OMEGA_C, points=omega_i[:BEAM_N_KEPT])
    # (b) each discarded mode's term integrated by quad and summed
    k_terms = sum(scipy.integrate.quad(lambda w, wi=wi, f=f: f / (wi ** 2 - w ** 2), 0.0,
                                       BEAM_OMEGA_C, epsabs=0.0, epsrel=1e-13)[0]
                  for wi, f in zip(omega_i[BEAM_N_KEPT:], F_i[BEAM_N_KEPT:])) / BEAM_OMEGA_C
    # (c) the SPEC §4 formula written with ln
    w_out, f_out = omega_i[BEAM_N_KEPT:], F_i[BEAM_N_KEPT:]
    k_spec = np.sum(f_out / w_out * np.log((w_out + BEAM_OMEGA_C) / (w_out - BEAM_OMEGA_C)))
    k_spec /= 2 * BEAM_OMEGA_C
    print(f"K_opt closed form {k_opt:.15e}, data-based quad {k_num:.15e}, "
          f"termwise quad {k_terms:.15e}")
    assert abs(k_num / k_opt - 1) < 1e-10
    assert abs(k_terms / k_opt - 1) < 1e-10
    assert abs(k_spec / k_opt - 1) < 1e-12
    # K_opt beats the static-compliance choice sum F_i/omega_i^2 in the band's H2 cost
    k_static = np.sum(f_out / w_out ** 2)
    w = np.linspace(0.0, BEAM_OMEGA_C, 4001)
    resid = np.sum(f_out / (w_out ** 2 - w[:, None] ** 2), axis=1)
    cost = [scipy.integrate.trapezoid((resid - k) ** 2, w) for k in (k_opt, k_static)]
    assert cost[0] < cost[1]


def test_feedthrough_from_frequency_data_and_modal_model():
    omega_i, F_i = _beam_modes()
    k_opt = moheimani_kopt(omega_i, F_i, BEAM_N_KEPT, BEAM_OMEGA_C)
    w = np.linspace(0.05, 150.0, 30001)
    w = w[np.min(np.abs(w[:, None] - omega_i[None, :3]), axis=1) > 1e-3]
    data = FrequencyData(w, _modal_sum(omega_i, F_i)(w))
    truncated = modal_model(omega_i[:BEAM_N_KEPT], F_i[:BEAM_N_KEPT])
    k_data = feedthrough_from_data(data, truncated, BEAM_OMEGA_C)
    assert abs(k_data / k_opt - 1) < 1e-4
    corrected = modal_model(omega_i[:BEAM_N_KEPT], F_i[:BEAM_N_KEPT], feedthrough=k_opt)
    assert abs(corrected.frequency_response(np.array([30.0]))[0]
               - truncated.frequency_response(np.array([30.0]))[0] - k_opt) < 1e-12


def test_moheimani_rejects_cutoff_above_discarded_mode():
    omega_i, F_i = _beam_modes()
    with pytest.raises(OptionError, match="below every discarded mode"):
        moheimani_kopt(omega_i, F_i, BEAM_N_KEPT, 200.0)


# ----------------------------------------------------------------------------- balanced truncation


def _eighth_order_model():
    st = Structure(4, integrator=False, delay=True)
    beta = [0.01, 2.0,
            1, 0.1, 1.0, 1, 0.05, 1.2,
            1, 0.2, 3.0, 1, 0.1, 2.5,
            1, 0.3, 8.0, 1, 0.2, 10.0,
            1, 0.5, 30.0, 1, 0.4, 25.0]
    return RationalDelayModel(st, np.array(beta, float))


def test_balanced_truncation_within_hsv_bound():
    model = _eighth_order_model()
    hsv = hankel_singular_values(model)
    assert hsv.shape == (8,) and np.all(np.diff(hsv) <= 0)
    omega = np.logspace(-3, 4, 20000)
    for r in (2, 4, 6):
        red = balanced_truncation(model, r)
        assert red.order == r and red.delay == model.delay and red.is_stable()
        err = np.max(np.abs(red.rational_response(omega) - model.rational_response(omega)))
        bound = balanced_truncation_error_bound(model, r)
        print(f"balanced truncation r={r}: H-inf error {err:.4f} <= bound {bound:.4f}")
        assert abs(bound - 2 * hsv[r:].sum()) < 1e-12
        assert err <= bound


def test_balanced_truncation_keeps_integrator():
    st = Structure(2, integrator=True, delay=False)
    model = RationalDelayModel(st, np.array([0, 4.0, 1, 0.1, 1, 1, 0.05, 1.2,
                                             1, 0.2, 3, 1, 0.1, 2.5]))
    assert hankel_singular_values(model).shape == (4,)       # stable part only
    red = balanced_truncation(model, 3)
    assert red.order == 3
    assert np.min(np.abs(red.poles())) < 1e-12               # the pole at 0 is kept
    unstable = StateSpaceModel(np.diag([1.0, 2.0]), [1, 1], [1, 1], 0.0)
    with pytest.raises(DataError, match="poles with Re >= 0"):
        balanced_truncation(unstable, 1)


# ----------------------------------------------------------------------------- peers


@pytest.mark.parametrize("fit", [aaa, vector_fitting])
def test_peer_reproduces_rational_system(fit):
    m = fit(_data4(), 4)
    err = _max_rel(m, OMEGA, _g4(OMEGA))
    print(f"{m.name} max rel error {err:.3e}")
    assert err <= 1e-8
    assert np.allclose(np.sort_complex(m.poles()), POLES4, atol=1e-7)


@pytest.mark.parametrize("fit", [aaa, vector_fitting, subspace])
def test_count_rhp_on_nonminimum_phase_system(fit):
    response = _tf_response(NUM_NMP, DEN_NMP, 1j * OMEGA)
    m = fit(FrequencyData(OMEGA, response), 3)
    assert _max_rel(m, OMEGA, response) <= 1e-8
    assert count_rhp(m) == (0, 1)
    assert m.is_stable() and not m.is_minimum_phase()
    assert np.min(np.abs(m.zeros() - 2.0)) < 1e-8


def test_vector_fitting_unstable_pole_and_flipping():
    num, den = np.polymul([1.0, 0.5, 9.0], [1.0, 2.0]), np.polymul([1.0, -1.0], [1.0, 0.3, 4.0])
    response = _tf_response(num, den, 1j * OMEGA)
    data = FrequencyData(OMEGA, response)
    free = vector_fitting(data, 3)
    assert count_rhp(free) == (1, 0) and _max_rel(free, OMEGA, response) < 1e-8
    flipped = vector_fitting(data, 3, enforce_stable_poles=True)
    assert count_rhp(flipped)[0] == 0


def test_count_rhp_known_model():
    # (s - 2)/((s + 1)(s - 3)) as a state space: one RHP pole, one RHP zero
    A = np.array([[-1.0, 0.0], [1.0, 3.0]])
    m = StateSpaceModel(A, [1.0, 0.0], [0.0, 1.0], 0.0)    # 1/((s+1)(s-3))
    assert count_rhp(m) == (1, 0)
    m2 = StateSpaceModel(A, [1.0, 0.0], [1.0, 1.0], 0.0)   # (s - 2)/((s+1)(s-3))
    assert count_rhp(m2) == (1, 1)


# ----------------------------------------------------------------------------- package hygiene


def test_every_public_name_has_a_docstring():
    for name in baselines.__all__:
        obj = getattr(baselines, name)
        assert obj.__doc__ and obj.__doc__.strip(), name


def test_import_does_not_load_control_or_matplotlib():
    code = ("import sys, freqid_casadi.baselines; "
            "print('matplotlib' in sys.modules, 'control' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "False"]

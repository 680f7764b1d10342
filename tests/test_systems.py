"""Tests of freqid_casadi.systems: the SPEC §4 benchmark systems."""

import numpy as np
import pytest
from scipy import integrate, optimize
from scipy.signal import argrelmax

from freqid_casadi import systems
from freqid_casadi.systems import _beams
from freqid_casadi.core.data import FrequencyData
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.systems import (
    G_A, G_A_at, G_B, G_B_at, G_C, G_C_at, G_D, G_D_at, moheimani_at, moheimani_beam,
    moheimani_kopt, moheimani_modes, perturbed, sqrt_inverse, sqrt_inverse_at, thesis_grid,
)

mp = pytest.importorskip("mpmath")

WIDE = np.logspace(-8, 5, 261)  # rad/s, wider than the thesis grid on both sides


# ------------------------------------------------------------------ high-precision references
# The SPEC §4 formulas written literally, evaluated with 60 significant digits (mpmath has an
# unbounded exponent, so neither the cancellation at small s nor the growth at large s hurts).


def _mp_G_A(w, h=0.01, eps1=0.001, eps2=0.0033):
    s = mp.mpc(0, w)
    m = mp.root(-s ** 2 / (1 + eps1 * s), 4)
    ratio = (mp.sinh(m) * mp.cos(m) - mp.cosh(m) * mp.sin(m)) / (
        m ** 3 * (mp.cos(m) * mp.cosh(m) - 1))
    return -s * mp.exp(-h * s) / ((eps1 * s + 1) * (eps2 * s + 1)) * ratio


def _mp_G_B(w, E=5, I=1, c_d=0.01, L=5.5):  # noqa: E741
    s = mp.mpc(0, w)
    m = mp.root(-s ** 2 / (E * I + s * c_d * I), 4)
    x = L * m
    N = mp.cosh(x) * mp.sin(x) - mp.sinh(x) * mp.cos(x)
    D = 1 + mp.cosh(x) * mp.cos(x)
    return N / (E * I * m ** 3 * D)


def _mp_G_C(w, lam=0.5, tau=0.0525, c=0.2, G=0.4, I_p=2.5, eps=0.001):
    s = mp.mpc(0, w)
    return (c / (G * I_p) * (mp.exp(-2 * tau * (1 - lam) * s) + 1)
            / ((eps * s + 1) - mp.exp(-2 * tau * s)) * mp.exp(-tau * lam * s))


def _reference(fun, omega):
    with mp.workdps(60):
        return np.array([complex(fun(float(w))) for w in omega])


@pytest.mark.parametrize("ours, ref", [(G_A_at, _mp_G_A), (G_B_at, _mp_G_B),
                                       (G_C_at, _mp_G_C)], ids=["A", "B", "C"])
def test_matches_high_precision_reference(ours, ref):
    # the wide range plus a dense stretch over the resonances of the thesis band
    omega = np.concatenate([WIDE, np.logspace(-1, 3, 240)])
    got = ours(1j * omega)
    want = _reference(ref, omega)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=0)


def test_series_and_rescaled_forms_agree_at_threshold():
    # both kernels around the circle |z| = SERIES_THRESHOLD, every direction
    z = systems.SERIES_THRESHOLD * np.exp(1j * np.linspace(-np.pi, np.pi, 361))
    m = _beams._fourth_root(z)
    a1, a2, r = _beams._scaled_beam_terms(m)
    q_series = _beams._horner(_beams._C_NUM, z) / _beams._horner(_beams._C_COSCOSH[1:], z)
    np.testing.assert_allclose(q_series, m * a1 / (a2 - r), rtol=1e-13)
    b_series = -_beams._horner(_beams._C_NUM, z) / (1 + _beams._horner(_beams._C_COSCOSH, z))
    np.testing.assert_allclose(b_series, -a1 / (m ** 3 * (a2 + r)), rtol=1e-13)


def test_fourth_root_branch():
    z = np.exp(1j * np.linspace(-np.pi, np.pi, 101)) * np.logspace(-3, 3, 101)
    m = _beams._fourth_root(z)
    np.testing.assert_allclose(m ** 4, z, rtol=1e-13)
    assert np.all(m.real >= 0) and np.all(m.imag >= 0)


# ------------------------------------------------------------------ limits and finiteness


def test_G_A_low_frequency_limit_is_4_over_s():
    w = 1e-8
    assert abs(G_A_at(1j * w) * 1j * w - 4) / 4 < 1e-9


def test_G_B_dc_gain():
    E, I, L = 5.0, 1.0, 5.5  # noqa: E741
    dc = L ** 3 / (3 * E * I)
    np.testing.assert_allclose(G_B_at(np.array([0.0, 1e-8j])), dc, rtol=1e-12)
    # also for other parameters
    np.testing.assert_allclose(G_B_at(1e-9j, E=2.0, I=3.0, L=2.0), 8 / 18, rtol=1e-12)


def test_G_C_low_frequency_limit():
    c, G, I_p, eps, tau = 0.2, 0.4, 2.5, 0.001, 0.0525
    limit = c / (G * I_p) * 2 / (eps + 2 * tau)
    w = 1e-8
    assert abs(G_C_at(1j * w) * 1j * w / limit - 1) < 1e-9


@pytest.mark.parametrize("fun", [G_A, G_B, G_C], ids=["A", "B", "C"])
def test_finite_on_wide_and_extended_grids(fun):
    for omega in (WIDE, np.logspace(3, 8, 200)):
        data = fun(omega)
        assert np.all(np.isfinite(data.response))
        assert np.all(data.response != 0)


def test_default_grids_and_names():
    omega = thesis_grid()
    assert omega.shape == (500,) and omega[0] == 1e-2 and omega[-1] == 1e3
    assert np.all(np.diff(np.log(omega)) > 0)
    for fun, name in [(G_A, "G_A"), (G_B, "G_B"), (G_C, "G_C")]:
        data = fun()
        assert isinstance(data, FrequencyData) and data.name == name
        np.testing.assert_array_equal(data.omega, omega)
    for fun, name in [(sqrt_inverse, "1/sqrt(s)"), (G_D, "G_D")]:
        data = fun()
        assert data.name == name and data.n_points == 500
        assert data.omega[0] == 1e-5 and data.omega[-1] == 1e5
    data = moheimani_beam()
    assert data.name == "moheimani_beam" and data.n_points == 500
    assert data.omega[0] == 1.0 and data.omega[-1] == 1e4


def test_delay_of_G_A():
    omega = thesis_grid()
    delayed = G_A(omega).response
    undelayed = G_A(omega, h=0.0).response
    np.testing.assert_allclose(delayed * np.exp(1j * omega * 0.01), undelayed, rtol=1e-13)
    # without the delay the low-frequency phase is the integrator's -90 deg
    assert abs(np.angle(undelayed[0], deg=True) + 90) < 0.1


def test_G_C_delay_and_poles():
    # integrator sign: the low-frequency phase is -90 deg (all other terms are O(omega tau))
    tau, lam = 0.0525, 0.5
    w = np.array([1e-6])
    phase = np.angle(G_C_at(1j * w) * np.exp(1j * w * tau * lam), deg=True)
    assert abs(phase[0] + 90) < 1e-5
    # the first resonance sits near pi/tau (poles of 1 - e^{-2 tau s})
    peak = _peak(lambda w: abs(G_C_at(1j * w)), 0.9 * np.pi / tau, 1.1 * np.pi / tau)
    assert abs(peak * tau / np.pi - 1) < 0.01


def test_fractional_systems():
    omega = np.logspace(-5, 5, 11)
    g = sqrt_inverse(omega).response
    np.testing.assert_allclose(np.abs(g), omega ** -0.5, rtol=1e-14)
    np.testing.assert_allclose(np.angle(g, deg=True), -45, atol=1e-12)
    np.testing.assert_allclose(sqrt_inverse_at(4j), (4j) ** -0.5, rtol=1e-15)
    gd = G_D(omega).response
    np.testing.assert_allclose(gd, 1 / (1 + 1 / g), rtol=1e-14)
    np.testing.assert_allclose(G_D_at(0.0), 1.0)


# ------------------------------------------------------------------ known facts


def test_G_B_has_12_resonances_in_band():
    w = thesis_grid(20000)
    mag = np.abs(G_B_at(1j * w))
    peaks = w[argrelmax(mag)[0]]
    assert peaks.size == 12
    assert 0.255 < peaks[0] < 0.265
    assert 96.0 < peaks[-1] < 97.0


def test_G_A_resonances_at_free_free_modes():
    # undamped free-free modes: cos m cosh m = 1, m_1 = 4.7300407, omega_1 ~ m_1^2
    w = 4.730040744862704 ** 2
    peak = _peak(lambda x: abs(G_A_at(1j * x)), 0.9 * w, 1.1 * w)
    assert abs(peak / w - 1) < 0.01


# ------------------------------------------------------------------ perturbed plants


def _peak(fun, lo, hi):
    res = optimize.minimize_scalar(lambda x: -fun(x), bounds=(lo, hi), method="bounded",
                                   options={"xatol": 1e-10 * hi})
    return res.x


@pytest.mark.parametrize("percent", [5, 10])
def test_perturbed_parameters(percent):
    f = 1 + percent / 100
    omega = thesis_grid()
    np.testing.assert_array_equal(
        perturbed("A", percent).response, G_A(omega, eps1=0.001 * f, eps2=0.0033 * f).response)
    np.testing.assert_array_equal(
        perturbed("B", percent).response, G_B(omega, E=5 * f, I=f).response)
    np.testing.assert_array_equal(
        perturbed("G_C", percent).response, G_C(omega, tau=0.0525 * f, lam=0.5 * f).response)
    assert perturbed("a", percent).name == f"G_A+{percent}%"


@pytest.mark.parametrize("percent", [5, 10])
def test_perturbed_resonances_shift(percent):
    f = 1 + percent / 100
    # B: E I -> f^2 E I, c_d I -> f c_d I: the lightly damped first mode moves by ~f
    w1 = 0.2599
    nominal = _peak(lambda x: abs(G_B_at(1j * x)), 0.8 * w1, 1.2 * w1)
    pert = _peak(lambda x: abs(G_B_at(1j * x, E=5 * f, I=f)), 0.8 * w1 * f, 1.2 * w1 * f)
    assert abs(pert / nominal / f - 1) < 1e-3
    # C: resonances near k pi / tau move by 1/f
    wc = np.pi / 0.0525
    nominal = _peak(lambda x: abs(G_C_at(1j * x)), 0.9 * wc, 1.1 * wc)
    pert = _peak(lambda x: abs(G_C_at(1j * x, tau=0.0525 * f, lam=0.5 * f)),
                 0.9 * wc / f, 1.1 * wc / f)
    assert abs(pert * f / nominal - 1) < 1e-3
    # A: eps1, eps2 are damping parameters: same low-frequency gain, relative change grows
    rel = np.abs(perturbed("A", percent).response / G_A().response - 1)
    assert rel[0] < 1e-4 and rel.max() > 0.1 * percent / 100


def test_perturbed_bad_input():
    with pytest.raises(OptionError, match="example"):
        perturbed("D", 5)
    with pytest.raises(OptionError, match="percent"):
        perturbed("A", -100)
    with pytest.raises(OptionError, match="percent"):
        perturbed("A", float("nan"))


# ------------------------------------------------------------------ Moheimani's beam


def test_moheimani_modes_formula():
    L, rho_A, EI, r = 1.3, 0.6265, 5.329, 0.075
    omega_i, F_i = moheimani_modes(30)
    i = np.arange(1, 31)
    assert omega_i.shape == F_i.shape == (30,)
    np.testing.assert_allclose(omega_i[0], (np.pi / L) ** 2 * np.sqrt(EI / rho_A), rtol=1e-15)
    np.testing.assert_allclose(omega_i / omega_i[0], i ** 2, rtol=1e-13)
    np.testing.assert_allclose(F_i, 2 / (rho_A * L) * np.sin(i * np.pi * r / L) ** 2,
                               rtol=1e-13)
    assert abs(omega_i[0] - 17.0324) < 1e-4


def test_moheimani_beam_response():
    data = moheimani_beam()
    omega_i, F_i = moheimani_modes(30)
    gap = np.min(np.abs(data.omega[:, None] / omega_i[None, :] - 1))
    assert gap > 1e-5  # the default grid avoids the modes
    np.testing.assert_allclose(data.response.imag, 0, atol=0)
    w = data.omega[7]
    np.testing.assert_allclose(data.response[7], np.sum(F_i / (omega_i ** 2 - w ** 2)),
                               rtol=1e-13)
    with pytest.raises(DataError, match="natural frequency"):
        moheimani_beam([1.0, omega_i[1]])


def test_moheimani_kopt_equals_integral_form():
    n_kept, omega_c = 2, 100.0
    k_opt = moheimani_kopt(n_kept, omega_c)

    def residual(w):  # Re(G - G_r)(j w), even in w
        return (moheimani_at(1j * w) - moheimani_at(1j * w, n_modes=n_kept)).real

    pieces = np.linspace(0.0, omega_c, 5)
    total = sum(integrate.quad(residual, a, b, epsabs=0, epsrel=1e-12)[0]
                for a, b in zip(pieces[:-1], pieces[1:]))
    k_num = 2 * total / (2 * omega_c)
    assert abs(k_opt / k_num - 1) < 1e-6
    assert k_opt > 0


def test_moheimani_kopt_bad_input():
    with pytest.raises(OptionError, match="omega_c"):
        moheimani_kopt(2, 200.0)  # omega_3 ~ 153 rad/s
    with pytest.raises(OptionError, match="n_kept"):
        moheimani_kopt(30, 10.0)


# ------------------------------------------------------------------ input checking


def test_bad_omega_and_parameters():
    with pytest.raises(DataError, match="omega"):
        G_A([1.0, 0.5])
    with pytest.raises(DataError, match="omega"):
        G_B([0.0, 1.0])
    with pytest.raises(OptionError, match="eps1"):
        G_A(eps1=-1.0)
    with pytest.raises(OptionError, match="lam"):
        G_C(lam=1.5)
    with pytest.raises(OptionError, match="n_points"):
        thesis_grid(1)
    with pytest.raises(OptionError, match="omega_min"):
        thesis_grid(10, 1.0, 0.1)


def test_all_names_have_docstrings():
    for name in systems.__all__:
        obj = getattr(systems, name)
        if callable(obj):
            assert obj.__doc__ and obj.__doc__.strip(), name


def test_catalogue_matches_the_systems_and_table_4_1():
    """The example catalogue: the thesis's structures and numbers (SPEC §5)."""
    from freqid_casadi.systems.examples import EXAMPLES, TABLE_4_1

    assert [(k, e.n_sections, e.integrator, e.order) for k, e in EXAMPLES.items()] == [
        ("A", 17, True, 34), ("B", 9, False, 18), ("C", 27, True, 54),
        ("fractional", 10, False, 10)]
    assert [(t.max_rel_error, t.subspace_max_rel_error, t.delay)
            for t in TABLE_4_1.values()] == [(0.2549, 2.5724, 0.0106),
                                             (0.0027, 0.0044, 0.011),
                                             (5.9884, 7.3382, 0.0261)]
    assert all(EXAMPLES[k].thesis.order == EXAMPLES[k].order for k in "ABC")
    omega = systems.thesis_grid(5)
    assert EXAMPLES["C"].data(omega).name == "G_C"
    np.testing.assert_array_equal(EXAMPLES["A"].truth(omega), systems.G_A(omega).response)

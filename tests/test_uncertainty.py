"""Tests of the multiplicative uncertainty weight (freqid_casadi.uncertainty.weight).

The synthetic relative error is a lead ``1e-3 |(1 + jw/10)/(1 + jw/1000)|`` times a ripple
``1 + 0.3 sin^2(3 ln w)`` (period ~0.45 decade, which no low-order weight can follow) on 300
log-spaced points over 1e-1..1e5 rad/s. Measured overbounds ``20 log10(|W|/e)`` (mean / max dB):
order 0: 21.11 / 42.27, order 1: 1.116 / 2.277, order 2: 1.116 / 2.277; order 2 with
margin 0.1: 1.944 / 3.105 (min 0.828 = 20 log10 1.1). A ripple-free order-4 shape (double
zero, real pole, resonant pole pair) needs order 3: order 2 gives 7.02 dB mean, order 3 0.435.
"""

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from freqid_casadi.uncertainty import weight as uncertainty
from freqid_casadi.core.data import FrequencyData
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.uncertainty.weight import (Overbound, WeightResult, WeightSection,
                                       fit_uncertainty_weight)

OMEGA = np.logspace(-1, 5, 300)
LEAD = 1e-3 * np.abs((1 + 1j * OMEGA / 10) / (1 + 1j * OMEGA / 1000))
REL_ERROR = LEAD * (1 + 0.3 * np.sin(3 * np.log(OMEGA)) ** 2)


@pytest.fixture(scope="module")
def weights():
    """Weights of order 0, 1, 2 for the synthetic curve (solved once)."""
    return {n: fit_uncertainty_weight(OMEGA, REL_ERROR, order=n) for n in (0, 1, 2)}


# --------------------------------------------------------------------------------------
# Bound, stability, order
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [0, 1, 2])
def test_bounds_every_point(weights, order):
    w = weights[order]
    assert isinstance(w, WeightResult)
    assert np.all(w.magnitude >= REL_ERROR)
    assert np.all(np.abs(w.frequency_response(OMEGA)) >= REL_ERROR)
    assert np.array_equal(w.magnitude, np.abs(w.frequency_response(OMEGA)))
    assert w.overbound.min_db >= 0.0
    assert w.gain_correction >= 1.0
    assert w.gain > 0


@pytest.mark.parametrize("order", [0, 1, 2])
def test_stable_and_minimum_phase(weights, order):
    w = weights[order]
    assert w.is_stable() and w.is_minimum_phase()
    assert np.all(w.poles().real < 0) and np.all(w.zeros().real < 0)
    sys = w.to_control()
    assert sys.nstates == order
    if order:
        assert np.all(sys.poles().real < 0)
        assert np.all(sys.zeros().real < 0)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_order_respected(weights, order):
    w = weights[order]
    assert w.order == order
    assert sum(s.order for s in w.sections) == order
    assert [s.order for s in w.sections] == [2] * (order // 2) + [1] * (order % 2)
    assert w.poles().size == order and w.zeros().size == order


def test_success_and_status(weights):
    for w in weights.values():
        assert w.success, w.message
        assert w.status >= 0


def test_message_is_a_sentence_and_the_optimiser_words_are_in_details(weights):
    for n, w in weights.items():
        assert w.message.startswith("ok: "), w.message
        assert "IPOPT" not in w.message and "Solve_" not in w.message
        assert f"{w.overbound.mean_db:.2g} dB above the error on average" in w.message
        assert w.details["solver_status"] in (("closed form",) if n == 0 else
                                              ("Solve_Succeeded", "Solved_To_Acceptable_Level"))
        assert w.details["start"] in (("closed form",) if n == 0 else ("fresh", "ladder"))
    from freqid_casadi.options import IpoptOptions

    short = fit_uncertainty_weight(OMEGA, REL_ERROR, order=2, method=IpoptOptions(max_iter=2))
    assert not short.success and short.details["solver_status"] == "Maximum_Iterations_Exceeded"
    assert short.message.startswith("not converged (iteration limit reached); the bound "
                                    "holds all the same")
    assert short.message.endswith("pass method=IpoptOptions(max_iter=20) to let it run "
                                  "further")
    assert np.all(short.magnitude >= short.rel_error * (1 - 1e-12))


def test_higher_order_overbounds_less(weights):
    mean = {n: w.overbound.mean_db for n, w in weights.items()}
    print(f"mean overbound dB: {mean}; max dB: "
          f"{ {n: w.overbound.max_db for n, w in weights.items()} }")
    assert mean[1] < mean[0] - 15.0          # measured 1.116 vs 21.11
    assert mean[2] <= mean[1] + 1e-9         # the ripple leaves nothing for order 2
    assert mean[1] < 1.5                     # ripple alone costs ~1.1 dB
    assert weights[2].objective <= weights[1].objective + 1e-12


def test_order_one_recovers_the_lead(weights):
    sec, = weights[1].sections
    assert sec.omega_num == pytest.approx(10.0, rel=0.05)
    assert sec.omega_den == pytest.approx(1000.0, rel=0.05)
    # W = 1.3 x lead: the ripple's peak factor on the lead
    assert weights[1].gain == pytest.approx(1.3e-3, rel=0.01)


def test_higher_order_follows_a_shape():
    """An order-4-like error with roll-off: order 3 fits it, order 2 cannot roll off."""
    w = OMEGA
    e = 1e-2 * np.abs((1 + 1j * w / 3) ** 2
                      / ((1 + 1j * w / 100) * (1 - (w / 3000) ** 2 + 2j * 0.3 * w / 3000)))
    e = e * (1 + 0.05 * np.cos(7 * np.log(w)))
    w2 = fit_uncertainty_weight(w, e, order=2)
    w3 = fit_uncertainty_weight(w, e, order=3)
    print(f"shape: order 2 {w2.overbound}, order 3 {w3.overbound}")
    for r in (w2, w3):
        assert np.all(r.magnitude >= e)
        assert r.is_stable() and r.is_minimum_phase()
    assert w3.overbound.mean_db < 1.0        # measured 0.435
    assert w3.overbound.mean_db < w2.overbound.mean_db - 5.0   # measured 7.02


def test_margin():
    w = fit_uncertainty_weight(OMEGA, REL_ERROR, order=2, margin=0.1)
    assert np.all(w.magnitude >= 1.1 * REL_ERROR)
    assert w.overbound.min_db >= 20 * math.log10(1.1) - 1e-12
    assert w.margin == 0.1
    assert w.is_stable() and w.is_minimum_phase()


# --------------------------------------------------------------------------------------
# One formula for numpy, complex numpy, CasADi and python-control
# --------------------------------------------------------------------------------------
def test_frequency_response_matches_poles_and_zeros(weights):
    w = weights[2]
    s = 1j * OMEGA
    ref = w.gain * np.ones_like(s)
    for z in w.zeros():
        ref *= 1 - s / z                      # unit DC gain per factor
    for p in w.poles():
        ref /= 1 - s / p
    np.testing.assert_allclose(w.frequency_response(OMEGA), ref, rtol=1e-10)
    sys = w.to_control()
    np.testing.assert_allclose(sys(s), ref, rtol=1e-9)
    assert abs(sys.dcgain()) == pytest.approx(w.gain, rel=1e-12)


@pytest.mark.parametrize("zetas", [(0.3, 2.0), (None, None)])
def test_section_formula_on_casadi_matches_complex(zetas):
    ca = pytest.importorskip("casadi")
    zn, zd = zetas
    sec = WeightSection(5.0, 300.0, zn, zd)
    omega = np.logspace(-1, 4, 7)
    yn, yd = ca.SX.sym("yn", 7), ca.SX.sym("yd", 7)
    expr = uncertainty._section_log_abs2(yn, zn, yd, zd, ca.log)
    fun = ca.Function("section_log_abs2", [yn, yd], [expr], ["y_num", "y_den"], ["l"])
    got = np.array(fun(omega / sec.omega_num, omega / sec.omega_den)).ravel()
    s = 1j * omega
    if zn is None:
        ref = (1 + s / 5.0) / (1 + s / 300.0)
    else:
        ref = ((1 + 2 * zn * s / 5.0 + (s / 5.0) ** 2)
               / (1 + 2 * zd * s / 300.0 + (s / 300.0) ** 2))
    np.testing.assert_allclose(got, np.log(np.abs(ref) ** 2), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sec.frequency_response(omega), ref, rtol=1e-12)


# --------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------
def test_accepts_a_fit_result():
    """A FitResult stand-in: only ``.data.omega`` and ``.rel_error`` are used."""
    omega, e = OMEGA[::3], REL_ERROR[::3]
    stand_in = SimpleNamespace(data=FrequencyData(omega, np.ones(omega.size)), rel_error=e)
    w = fit_uncertainty_weight(stand_in, order=1)
    direct = fit_uncertainty_weight(omega, e, order=1)
    assert np.array_equal(w.omega, omega) and np.array_equal(w.rel_error, e)
    assert w.gain == direct.gain and w.sections == direct.sections
    assert np.all(w.magnitude >= e)
    with pytest.raises(DataError, match="not both"):
        fit_uncertainty_weight(stand_in, e, order=1)


def test_zero_rel_error_points_are_handled():
    e = REL_ERROR.copy()
    e[[0, 17, 150]] = 0.0
    w = fit_uncertainty_weight(OMEGA, e, order=1)
    assert np.all(w.magnitude >= e)
    assert np.all(np.isfinite(w.magnitude)) and np.isfinite(w.overbound.max_db)
    assert w.overbound.mean_db < 2.0


def test_result_is_frozen(weights):
    w = weights[1]
    with pytest.raises(dataclasses.FrozenInstanceError):
        w.gain = 1.0
    with pytest.raises(ValueError):
        w.magnitude[0] = 0.0
    assert isinstance(w.overbound, Overbound)


@pytest.mark.parametrize("args, kwargs, error, match", [
    ((OMEGA, -REL_ERROR), {}, DataError, r"rel_error must be >= 0.*rel_error\[0\]"),
    ((OMEGA, np.where(np.arange(300) == 5, np.nan, REL_ERROR)), {}, DataError,
     r"rel_error must be finite: rel_error\[5\]=nan"),
    ((OMEGA, REL_ERROR[:-1]), {}, DataError, r"equal lengths: len\(omega\)=300"),
    ((OMEGA, np.zeros(300)), {}, DataError, "zero at every point"),
    ((OMEGA[::-1], REL_ERROR), {}, DataError, "strictly increasing"),
    ((-OMEGA, REL_ERROR), {}, DataError, r"omega must be finite and > 0"),
    ((OMEGA,), {}, DataError, "rel_error is missing"),
    ((OMEGA, REL_ERROR), {"order": -1}, OptionError, r"order must be >= 0.*got -1"),
    ((OMEGA, REL_ERROR), {"order": 1.5}, OptionError, "order must be an integer"),
    ((OMEGA, REL_ERROR), {"order": True}, OptionError, "order must be an integer"),
    ((OMEGA, REL_ERROR), {"margin": -0.1}, OptionError, "margin must be"),
    ((OMEGA, REL_ERROR), {"margin": math.nan}, OptionError, "margin must be"),
    ((OMEGA, REL_ERROR), {"max_iter": 0}, OptionError, "max_iter"),
    ((OMEGA, REL_ERROR), {"min_damping": 0.0}, OptionError, "min_damping"),
    ((OMEGA[:4], REL_ERROR[:4]), {"order": 2}, DataError, "too few points for order 2"),
])
def test_bad_input(args, kwargs, error, match):
    with pytest.raises(error, match=match):
        fit_uncertainty_weight(*args, **kwargs)


def test_docstrings():
    for name in uncertainty.__all__:
        obj = getattr(uncertainty, name)
        if callable(obj):
            assert obj.__doc__ and obj.__doc__.strip(), name

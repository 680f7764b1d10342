"""Adversarial inputs to the model and data classes and the FRF estimator (fuzz pass).

Each case failed before its fix: ``Structure(integrator="no")`` built a model with an
integrator, array-valued fields raised ValueError from ``if array``, complex or text beta
were silently cast or raised ValueError, ``to_control(pade_order=...)`` raised ValueError or
ZeroDivisionError, ``FrequencyData.sorted`` with too few weights raised IndexError,
``window(2.7)`` cut to 2 points silently, and ``frf_from_records`` at an extreme sampling
frequency found "no frequency has coherence >= None (highest 0)".
"""

import warnings

import numpy as np
import pytest

from freqid_casadi.core.data import FrequencyData
from freqid_casadi.errors import DataError, OptionError, StructureError
from freqid_casadi.experiment import frf_from_records
from freqid_casadi.core.model import RationalDelayModel, Structure
from conftest import ONE_SECTION_BETA  # noqa: E402

BETA = ONE_SECTION_BETA
MODEL = RationalDelayModel(Structure(1), BETA)
W = np.logspace(-1, 2, 40)


@pytest.mark.parametrize("kw, needle", [
    (dict(integrator="no"),
     r"integrator must be True, False or an integer k with \|k\| <= 3 .*, got 'no'"),
    (dict(delay="no"), "delay must be True or False, got 'no'"),
    (dict(delay=None), "delay must be True or False, got None"),
    (dict(basis=np.array(["a", "b"])), "unknown basis array"),
    (dict(zeros=np.array(["a", "b"])), "unknown zeros array"),
    (dict(gain_sign=np.array([1, 1])), "gain_sign must be 1 or -1"),
    (dict(gain_sign=1.0 + 0j), "gain_sign must be 1 or -1"),
])
def test_structure_fields_of_a_wrong_type(kw, needle):
    with pytest.raises(StructureError, match=needle):
        Structure(1, **kw)


def test_structure_keeps_taking_numpy_and_0_1_flags():
    s = Structure(np.int64(1), integrator=np.bool_(True), delay=0, gain_sign=np.int64(-1))
    assert (s.integrator, s.delay, s.gain_sign) == (True, False, -1)


@pytest.mark.parametrize("beta, needle", [
    (np.ones(8) + 1j, "complex values"),
    (["a"] * 8, "must be an array of real numbers"),
    (np.ones((2, 4)), r"one-dimensional.*shape \(2, 4\)"),
])
def test_beta_that_is_not_a_real_vector(beta, needle):
    with pytest.raises(StructureError, match=needle):
        RationalDelayModel(Structure(1), beta)


@pytest.mark.parametrize("order, needle", [
    (-1, "pade_order must be an integer >= 1"),
    (0, r"pade_order must be an integer >= 1 \(the order of the delay's Pade approximation; "
        r"0 would drop the delay"),
    ("x", "pade_order must be an integer >= 1"),
    (2.5, "pade_order must be an integer >= 1"),
    (1000, "pade_order=1000 is too high"),
])
def test_bad_pade_order_is_an_option_error(order, needle):
    with pytest.raises(OptionError, match=needle):
        MODEL.to_control(pade_order=order)


def test_pade_order_still_works():
    sys = MODEL.to_control(pade_order=3)
    assert sys.delay == 0.0 and sys.nstates == 2 + 3
    g = sys(1j * 2.0)
    assert abs(complex(np.squeeze(g)) / MODEL.frequency_response(np.array([2.0]))[0] - 1) < 1e-6


def test_sorted_with_too_few_weights_is_a_data_error():
    with pytest.raises(DataError, match=r"len\(weights\)=3, len\(omega\)=40"):
        FrequencyData.sorted(W[::-1], np.ones(40), weights=np.ones(3))


@pytest.mark.parametrize("n", [2.7, "a", True])
def test_window_length_must_be_an_integer(n):
    data = FrequencyData(W, np.ones(40))
    with pytest.raises(DataError, match="window length must be an integer"):
        data.window(n)
    assert data.window(np.int64(3)).n_points == 3


@pytest.mark.parametrize("fs", [1e300, 1e-300, 1e-150])
def test_welch_at_an_extreme_sampling_frequency(fs):
    rng = np.random.default_rng(0)
    u = rng.standard_normal(4096)
    y = np.convolve(u, [0.5, 0.3, 0.1])[:4096]
    ref = frf_from_records(u, y, fs=1000.0, nperseg=256)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est = frf_from_records(u, y, fs=fs, nperseg=256)
    assert est.data.n_points == ref.data.n_points == 128
    np.testing.assert_allclose(est.data.response, ref.data.response, rtol=1e-13)
    np.testing.assert_allclose(est.data.omega / fs, ref.data.omega / 1000.0, rtol=1e-13)
    assert np.all(np.isfinite(est.data.weights))


def test_welch_coherence_message_has_the_digits_that_matter():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(4096)
    y = np.convolve(u, [0.5, 0.3, 0.1])[:4096]
    with pytest.raises(DataError, match=r"coherence >= 0\.999999 \(highest 0\.99998"):
        frf_from_records(u, y, fs=1000.0, nperseg=256, min_coherence=0.999999)


def test_stabilization_diagram_without_poles_draws_no_empty_legend():
    # before: matplotlib's "No artists with labels found to put in legend" reached the user
    # as a warning line of 'freqid modal' (one order, its pole outside the band)
    import matplotlib

    matplotlib.use("Agg")
    import freqid_casadi as fc
    from freqid_casadi.plots.modal import stabilization_diagram

    data = FrequencyData(W, MODEL.frequency_response(W), "plant")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # (the rational start's order-2 pole lies outside the band)
        res = fc.stabilization([data], (2,), delay=False, start="rational")
    # keep only the poles outside the band (the shared fit's peak start may now place the
    # order-2 pole inside it): the diagram then has nothing to label
    import dataclasses

    res = dataclasses.replace(res, poles=tuple(p for p in res.poles
                                               if not W[0] <= p.omega_n <= W[-1]), modes=())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = stabilization_diagram(res)
    assert fig.axes[0].get_legend() is None

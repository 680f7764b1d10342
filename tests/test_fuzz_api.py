"""Adversarial inputs to the public API that were not yet covered (fuzz pass).

Each case failed before its fix: a Python error (ValueError from ``if array``, TypeError),
a silent coercion (``integrator="no"`` fitted an integrator), a misleading error (weights 0
at the lowest frequency gave "weights are all zero"), a result that depended on the scale
of the weights (uniform weights 1e4 "not converged", 1e-200 stopped at the start) or a
non-finite number in a result (the RMS error overflowed to inf). The fits are one section on
40 points (a fraction of a second each).
"""

import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.fitting import batch
from freqid_casadi.fitting import sweep
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.core.metrics import error_stats
from freqid_casadi.core.model import RationalDelayModel, Structure
from conftest import one_section_model  # noqa: E402

W = np.logspace(-1, 2, 40)
MODEL = one_section_model()
R = MODEL.frequency_response(W)
DATA = fc.FrequencyData(W, R, "plant")


def _fit(**kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fc.fit(W, R, **{"n_sections": 1, **kw})


# ----------------------------------------------------------------------- fit: options
@pytest.mark.parametrize("kw, exc, needle", [
    (dict(integrator="no"), OptionError,
     "integrator must be 'auto', True, False or an integer k .*, got 'no'"),
    (dict(delay="False"), OptionError, "delay must be True or False, got 'False'"),
    (dict(delay=None), OptionError, "delay must be True or False, got None"),
    (dict(integrator=np.array([1, 0])), OptionError,
     "integrator must be True, False or an integer k"),
    (dict(basis=np.array(["a", "b"])), OptionError, "unknown basis array"),
    (dict(start=np.array([1, 2])), OptionError, "unknown start array"),
    (dict(objective=np.array([1, 2])), OptionError, "unknown objective array"),
    (dict(progress=np.array([1, 2])), OptionError, "progress must be True, False, 'lines' or "
                                                   "a callable"),
    (dict(progress="yes"), OptionError, "progress must be True, False, 'lines' or a callable"),
    (dict(tol=True), OptionError, "tol must be a number > 0"),
], ids=lambda v: str(v)[:40] if isinstance(v, dict) else None)
def test_fit_option_of_a_wrong_type_is_an_option_error(kw, exc, needle):
    with pytest.raises(exc, match=needle.replace("(", r"\(").replace(")", r"\)")):
        _fit(**kw)


@pytest.mark.parametrize("kw", [dict(tol=np.float32(0.5)), dict(min_damping=np.int64(0)),
                                dict(integrator=np.bool_(False), delay=np.bool_(True)),
                                dict(integrator=0, delay=1)])
def test_fit_takes_numpy_scalars_and_0_1_flags(kw):
    res = _fit(**kw)
    assert res.success and res.max_rel_error < 1e-10
    assert res.options.integrator is False and res.options.delay is True


def test_fit_missing_data_names_the_data():
    with pytest.raises(DataError, match="the data are missing"):
        fc.fit(None, R, n_sections=1)


def test_fit_band_of_300_decades_is_a_data_error_not_an_internal_one():
    # before: StructureError "internal: each dc-gauge variable must enter exactly one ..."
    with pytest.raises(DataError, match=r"omega spans 300 decades.*narrower band"):
        fc.fit(np.logspace(-150, 150, 40), R, n_sections=1)


# ----------------------------------------------------------------------- fit: weights
@pytest.mark.parametrize("scale", [1e-200, 1e-16, 1e4, 1e200])
def test_uniform_weights_of_any_scale_give_the_unweighted_fit(scale):
    # before: 1e4 and 1e200 "not converged" at 2e-16; 1e-200 stopped at max error 0.976
    res = _fit(weights=np.full(W.size, scale))
    assert res.success, res.message
    assert res.max_rel_error < 1e-12
    assert res.delay == pytest.approx(0.01, rel=1e-9)
    assert res.data.weights[0] == scale                 # the user's weights are kept


def test_weight_zero_at_the_lowest_frequency_is_fitted():
    # before: DataError "weights are all zero: at least one point must count" (stage 0's
    # first window is the lowest point)
    w = np.ones(W.size)
    w[:3] = 0.0
    res = _fit(weights=w)
    assert res.success and res.max_rel_error < 1e-10
    assert res.rel_error.shape == (W.size,)             # the error still over all points


def test_fewer_weighted_points_than_parameters_is_refused():
    # before: "converged" with max rel. error 0.977 (any model through 5 points)
    w = np.r_[np.ones(5), np.zeros(35)]
    with pytest.raises(DataError, match="5 points with weight > 0 for 8 parameters"):
        _fit(weights=w)


# ----------------------------------------------------------------------- finite results
def test_rms_of_huge_errors_is_finite():
    stats = error_stats(np.array([1e300, 1e300, 0.0]))
    assert stats.rms == pytest.approx(1e300 * np.sqrt(2 / 3), rel=1e-14)
    assert error_stats(np.array([3e-300, 4e-300])).rms == pytest.approx(
        np.sqrt(12.5) * 1e-300, rel=1e-14)
    assert error_stats(np.array([1.0, 2.0])).rms == np.sqrt(2.5)      # the plain formula


def test_fit_of_600_decades_of_magnitude_reports_finite_errors():
    # before: rms_rel_error = inf (the squares of 1e294 overflowed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fc.fit(W, R * np.logspace(-300, 300, W.size), n_sections=1)
    assert np.isfinite(res.rms_rel_error) and np.isfinite(res.max_rel_error)
    assert np.all(np.isfinite(res.rel_error))
    assert not res.success


# ----------------------------------------------------------------------- fit_shared
@pytest.mark.parametrize("kw, needle", [
    (dict(delay=np.array([1, 2])), "unknown delay array"),
    (dict(zeros=None), "unknown zeros None; choose one of minimum-phase, free"),
    (dict(start=np.array([1, 2])), "unknown start array"),
    (dict(integrator="no"), "integrator must be True or False"),
    (dict(balance_channels="no"), "balance_channels must be True or False"),
    (dict(progress=np.array([1, 2])), "progress must be True, False, 'lines' or a callable"),
    (dict(delay_max=-1.0), "delay_max must be a finite delay > 0"),
    (dict(delay_max=float("nan")), "delay_max must be a finite delay > 0"),
    (dict(delay_max="x"), "delay_max must be a finite delay > 0"),
    (dict(max_iter=-5), "max_iter must be an integer >= 1"),
    (dict(max_iter=1.5), "max_iter must be an integer >= 1"),
    (dict(n_vf_iter=-1), "n_vf_iter must be an integer >= 0"),
    (dict(n_vf_iter="a"), "n_vf_iter must be an integer >= 0"),
])
def test_fit_shared_options_are_checked(kw, needle):
    with pytest.raises(OptionError, match=needle):
        fc.fit_shared([DATA, DATA], 1, **kw)


def test_fit_shared_with_more_parameters_than_points_is_refused():
    # before: 30 shared sections on 2 x 40 points returned a "result"
    with pytest.raises(DataError, match="80 weighted points over 2 channels for 184"):
        fc.fit_shared([DATA, DATA], 30)


def test_fit_shared_weights_of_any_scale():
    # before: weights=1e-300 gave delay 0 and gain 16.7 (the start, unpolished)
    res = fc.fit_shared([DATA, DATA], 1, weights=1e-300)
    assert np.all(res.max_rel_errors < 1e-8)
    assert [m.delay for m in res.models] == pytest.approx([0.01, 0.01], rel=1e-6)


# ----------------------------------------------------------------------- sweep, fit_many
@pytest.mark.parametrize("args, kw, exc, needle", [
    ([None], {}, OptionError, "orders must be a list of even integers"),
    ([[2.5]], {}, OptionError, r"orders must be integers, got 2\.5"),
    ([[2]], dict(target="x"), OptionError, "target must be a number > 0"),
    ([[2]], dict(target=np.array([1, 2])), OptionError, "target must be a number > 0"),
    ([[2]], dict(progress="x"), OptionError, "progress must be True, False, 'lines' or a callable"),
    ([[2]], dict(truth=lambda w: w * np.nan), DataError, "truth.omega. must return one "
                                                         "finite"),
])
def test_sweep_arguments_are_checked(args, kw, exc, needle):
    with pytest.raises(exc, match=needle):
        sweep.sweep(DATA, *args, **kw)


def test_sweep_takes_an_order_string():
    res = sweep.sweep(DATA, "2")
    assert [r.order for r in res.rows] == [2] and res.rows[0].max_rel_error < 1e-10


@pytest.mark.parametrize("args, kw, exc, needle", [
    ([None], dict(n_sections=1), DataError, "datasets must be a list"),
    ([["x.csv"]], dict(n_sections=1, load_options={"zzz": 1}), OptionError,
     "unknown load option.*'zzz'"),
    ([["x.csv"]], dict(n_sections=1, load_options="x"), OptionError,
     "load_options must be a dict"),
])
def test_fit_many_arguments_are_checked(args, kw, exc, needle):
    with pytest.raises(exc, match=needle):
        batch.fit_many(*args, **kw)


def test_fit_many_takes_a_numpy_job_count():
    items = batch.fit_many([DATA], n_sections=1, n_jobs=np.int64(1))
    assert items[0].ok and items[0].result.max_rel_error < 1e-10


# ----------------------------------------------------------------------- stabilization
@pytest.mark.parametrize("args, kw, needle", [
    ([None], {}, "orders must be a sequence of even integers"),
    ([[2.0]], {}, r"orders must be integers, got \(2\.0,\)"),
    ([[2]], dict(freq_tol="x"), "freq_tol must be a number, got 'x'"),
    ([[2]], dict(freq_tol=np.array([0.1, 0.2])), "freq_tol must be a number"),
    ([[2]], dict(min_stable="x"), "min_stable must be an integer >= 1"),
    ([[2]], dict(min_stable=0), "min_stable must be an integer >= 1"),
    ([[2]], dict(min_stable=1.5), "min_stable must be an integer >= 1"),
])
def test_stabilization_arguments_are_checked(args, kw, needle):
    # before: TypeError/ValueError, or min_stable=0 and 1.5 accepted
    with pytest.raises(OptionError, match=needle):
        fc.stabilization([DATA], *args, **kw)


def test_stabilization_takes_an_order_string():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fc.stabilization([DATA], "2:4:2", delay="per-channel")
    assert res.orders == (2, 4)


# ----------------------------------------------------------------------- resolution
def test_delay_bound_and_damping_floor_of_bad_frequencies():
    from freqid_casadi.fitting.fit import default_delay_max, resolution_damping

    # before: -pi (a negative delay bound) for decreasing omega, NaN for a NaN frequency
    with pytest.raises(DataError, match="strictly increasing"):
        default_delay_max([2.0, 1.0])
    with pytest.raises(DataError, match="finite frequencies"):
        resolution_damping([1.0, np.nan])
    with pytest.raises(OptionError, match="fraction must be a finite number > 0"):
        resolution_damping(W, fraction=-1.0)
    assert default_delay_max([2.0]) == np.pi / 2.0           # one point: unchanged
    assert default_delay_max(W) == np.pi / np.max(np.diff(W))


# ----------------------------------------------------------------------- series of fits
def test_sweep_refuses_a_too_large_order_before_fitting_the_others(monkeypatch):
    # before: orders 2..12 were fitted, then order 14 raised (all that work lost)
    calls = []
    real = sweep.fit
    monkeypatch.setattr(sweep, "fit", lambda *a, **k: calls.append(k) or real(*a, **k))
    with pytest.raises(DataError, match="too few data points for 7 sections: 40 points"):
        sweep.sweep(DATA, [2, 4, 6, 8, 10, 12, 14])
    assert calls == []


def test_stabilization_refuses_a_too_large_order_before_fitting_the_others(monkeypatch):
    from freqid_casadi.modal import shared

    calls = []
    real = shared.fit_shared
    monkeypatch.setattr(shared, "fit_shared", lambda *a, **k: calls.append(k) or real(*a, **k))
    with pytest.raises(DataError, match="too few data points for 14 shared sections"):
        fc.stabilization([DATA, DATA], "2:28:2")
    assert calls == []


def test_a_subnormal_response_is_named_as_the_user_gave_it():
    # before: "response[5]=0 at omega=0.0606..." (the scaled point, which underflowed)
    r = R.copy()
    r[5] = 5e-324
    with pytest.raises(DataError, match=r"response\[5\]=\(?5e-324.* at omega=0\.2"):
        fc.fit(W, r, n_sections=1)


def test_barrier_lm_without_one_accepted_step_is_not_converged():
    # a damping of 1e300 makes every step vanish from the start: the outer loop ran out
    # and the stage said "converged" at its start point (found by the fuzz pass)
    res = fc.fit(W, R, n_sections=1, method=fc.BarrierLMOptions(tau=1e300))
    assert not res.success
    assert res.stages[-1].solver_status == "no_step_accepted"
    ok = fc.fit(W, R, n_sections=1, method=fc.BarrierLMOptions())
    assert ok.success and ok.max_rel_error < 1e-9

"""Tests of the option objects (freqid_casadi.options) and fit()'s keyword contract."""

import dataclasses
import inspect
import pickle

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.fitting.stages import StageKind
from freqid_casadi.errors import OptionError
from freqid_casadi.options import (LEGACY_KEYWORDS, BarrierLMOptions, IpoptOptions,
                                   LoopOptions, options_from_keywords, solver_options)


def test_fit_signature_is_small_and_explicit():
    params = inspect.signature(fc.fit).parameters
    # a small signature: at most 18 keywords (the 18th, n_jobs, is the package-wide
    # spelling of worker processes, as fit_many, bootstrap and stabilization take it)
    assert len(params) <= 18
    assert not any(p.kind == p.VAR_KEYWORD for p in params.values())
    assert "loop" in params and "solver" not in params
    assert not set(params) & set(LEGACY_KEYWORDS)


@pytest.mark.parametrize("name, value, expect", [
    ("hessian", "gauss-newton", "method=IpoptOptions(hessian='gauss-newton')"),
    ("gauge", "b1", "loop=LoopOptions(gauge='b1')"),
    ("delay_max", 0.1, "loop=LoopOptions(delay_max=0.1)"),
    ("ipopt_options", {"tol": 1e-9}, "method=IpoptOptions(ipopt={'tol': 1e-09})"),
    ("lm_options", {"max_inner": 50}, "method=BarrierLMOptions(max_inner=50)"),
    ("final_max_iter", 500, "IpoptOptions(final_max_iter=500)"),
])
def test_old_keyword_names_its_new_home(name, value, expect):
    data = fc.systems.G_A()
    with pytest.raises(TypeError, match=r"fit\(\) no longer takes " + name + "=") as info:
        fc.fit(data, n_sections=1, **{name: value})
    assert expect in str(info.value)


def test_every_old_keyword_is_rejected_before_any_work():
    for name in LEGACY_KEYWORDS:
        with pytest.raises(TypeError, match=name):
            fc.fit(None, n_sections=1, **{name: None})


@pytest.mark.parametrize("cls, kwargs, match", [
    (IpoptOptions, {"hessian": "bfgs"}, r"unknown hessian 'bfgs'.*IpoptOptions.hessian"),
    (IpoptOptions, {"hessian": "exact-clip"}, "unknown hessian"),
    (IpoptOptions, {"warm_start": "yes"}, "unknown warm_start"),
    (IpoptOptions, {"max_iter": 0}, r"IpoptOptions.max_iter must be an integer >= 1, got 0"),
    (IpoptOptions, {"final_max_iter": 2.5}, "final_max_iter must be an integer"),
    (IpoptOptions, {"ipopt": 3}, "IpoptOptions.ipopt must be a dict"),
    (IpoptOptions, {"ipopt": {1: 2}}, "IpoptOptions.ipopt must be a dict"),
    (BarrierLMOptions, {"damping": "x"}, "unknown damping"),
    (BarrierLMOptions, {"t_factor": 1.0}, r"t_factor must be a finite real number > 1"),
    (BarrierLMOptions, {"t_max": 0.5}, r"t_max must be >= t0"),
    (BarrierLMOptions, {"tau": float("nan")}, "tau must be"),
    (BarrierLMOptions, {"eps2": -1.0}, r"eps2 must be a finite real number >= 0"),
    (BarrierLMOptions, {"max_inner": True}, "max_inner must be an integer"),
    (LoopOptions, {"gauge": "b2"}, "unknown gauge 'b2'"),
    (LoopOptions, {"init": "random"}, "unknown init"),
    (LoopOptions, {"scale_l": 0.5}, r"scale_l must be a finite real number >= 1"),
    (LoopOptions, {"scaled": "yes"}, "scaled must be True or False"),
    (LoopOptions, {"delay_max": 0.0}, r"delay_max \(seconds\) must be a finite real number > 0"),
    (LoopOptions, {"delay_max": -1.0}, "got -1.0"),
    (LoopOptions, {"derivatives": "fd"}, "unknown derivatives 'fd'"),
    (LoopOptions, {"gauge": "b1", "derivatives": "affine"}, "needs gauge='dc'"),
])
def test_options_validate_themselves(cls, kwargs, match):
    with pytest.raises(OptionError, match=match):
        cls(**kwargs)


def test_options_are_frozen_hashable_and_picklable():
    opts = IpoptOptions(ipopt={"tol": 1e-9, "acceptable_iter": 5})
    assert opts.ipopt == (("acceptable_iter", 5), ("tol", 1e-9))
    assert opts.ipopt_dict() == {"acceptable_iter": 5, "tol": 1e-9}
    assert IpoptOptions().ipopt_dict() is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.hessian = "gauss-newton"
    for obj in (opts, BarrierLMOptions(damping="marquardt"), LoopOptions(delay_max=0.2)):
        assert pickle.loads(pickle.dumps(obj)) == obj
        assert hash(obj) == hash(dataclasses.replace(obj))


def test_barrier_lm_defaults_are_the_solvers_defaults():
    from freqid_casadi.solvers.barrier_lm import barrier_lm

    sig = inspect.signature(barrier_lm).parameters
    for name, value in BarrierLMOptions().lm_kwargs().items():
        assert sig[name].default == value, name


def test_solver_options_and_translation():
    assert solver_options("ipopt") == IpoptOptions()
    assert solver_options("barrier-lm") == BarrierLMOptions()
    lm = BarrierLMOptions(max_inner=7)
    assert solver_options(lm) is lm
    with pytest.raises(OptionError, match="unknown method 'newton'"):
        solver_options("newton")
    solver, loop = options_from_keywords("barrier-lm", gauge="b1", hessian="exact",
                                         lm_options={"damping": "marquardt"}, max_iter=7)
    assert solver == BarrierLMOptions(damping="marquardt", max_iter=7)
    assert loop == LoopOptions(gauge="b1")
    solver, _ = options_from_keywords(hessian="gauss-newton", ipopt_options={"tol": 1e-8})
    assert solver == IpoptOptions(hessian="gauss-newton", ipopt={"tol": 1e-8})
    with pytest.raises(OptionError, match="unknown option"):
        options_from_keywords(solver="x")


def test_fit_records_typed_options_and_computed_numbers():
    data = fc.systems.G_A().window(120)
    # (without the resolution guard, which would refit with the damping floor: this
    # window's free 2-section fit has a pole narrower than the spacing)
    loop = LoopOptions(delay_max=0.05, resolution_guard=False)
    res = fc.fit(data, n_sections=2, integrator=True, start="sequential",
                 method=IpoptOptions(hessian="gauss-newton"), loop=loop)
    assert res.method == "ipopt" and res.options.method == "ipopt"
    assert res.options.solver == IpoptOptions(hessian="gauss-newton")
    assert res.options.loop is loop
    assert res.delay_max == 0.05 and res.zeta_min is None
    assert set(res.start_max_rel_errors) == {"sequential"}
    assert res.start_max_rel_errors["sequential"] == pytest.approx(res.max_rel_error,
                                                                   rel=1e-12)
    flat = res.options.as_dict()
    assert flat["hessian"] == "gauss-newton" and flat["gauge"] == "dc"
    assert flat["ipopt"] == {}
    assert np.isfinite(res.max_rel_error)


def test_final_stage_false_runs_no_final_stage():
    """A defect: ``final_stage and window < m or status == MAX_ITER`` ran a
    final stage with final_stage=False after a stage that hit its iteration limit."""
    data = fc.systems.G_A().window(200)
    # (hold_delay=False: this unconverged fit's delay, 13 ms with a std of 29 s and a lag of
    # 0.013 rad at the window's top, would be held at 0 by a refit without a delay, which
    # converges: the result would then be that refit, whose stages are not the premise)
    res = fc.fit(data, n_sections=3, integrator=True, method=IpoptOptions(max_iter=1),
                 loop=LoopOptions(final_stage=False, hold_delay=False), start="sequential")
    # (which stages hit the 1-iteration limit depends on the BLAS kernel: under
    # OPENBLAS_CORETYPE=Prescott the last two converge in one iteration)
    assert any(s.status.name == "MAX_ITER" for s in res.stages)
    assert not any(s.kind == StageKind.FINAL for s in res.stages)
    assert max(s.stage for s in res.stages) == 3


def test_flags_follow_one_rule_everywhere():
    # fit(integrator=1) was accepted while LoopOptions(scaled=1) raised: one rule now
    assert LoopOptions(scaled=1, final_stage=np.False_).scaled is True
    assert LoopOptions(final_stage=np.False_).final_stage is False
    for bad in ("no", 2, None, 0.5):
        with pytest.raises(OptionError, match="scaled must be True or False, got .*; pass "
                           "scaled=True or scaled=False"):
            LoopOptions(scaled=bad)

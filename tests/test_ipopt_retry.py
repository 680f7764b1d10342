"""The one repeated solve of solvers/ipopt.run_nlpsol: after a failed step computation
(with the Hessian's regularisation allowed further) and after IPOPT's point left the bounds
(its slack correction moved a bound) where projecting it costs (with the bounds held
exactly). Both are provoked deterministically: small problems whose IPOPT path is the same
under every BLAS kernel."""

import casadi as ca
import numpy as np
import pytest

from freqid_casadi.solvers import ipopt


def _toy(c, x_start):
    """``min (x + y)^2 + (y - c)^2``, ``x >= 0``: unconstrained optimum (-c, c) with cost 0,
    constrained (0, c/2) with cost c^2/2; the objective scaled by 1/cost(start) as the
    stages do, so the multiplier of ``x >= 0`` is ~1/c in IPOPT's units."""
    def cost(v):
        return float((v[0] + v[1]) ** 2 + (v[1] - c) ** 2)

    z = ca.MX.sym("z", 2)
    nlp = {"x": z, "f": (z[0] + z[1]) ** 2 + (z[1] - c) ** 2}
    x0 = np.array([x_start, 0.0])
    opts = ipopt.base_options(200, 1e-12, False)
    opts["ipopt"].update(obj_scaling_factor=1.0 / cost(x0), nlp_scaling_method="none")
    return nlp, opts, x0, np.array([0.0, -np.inf]), np.array([np.inf, np.inf]), cost


def test_a_point_outside_its_bound_is_solved_again_with_the_bound_held():
    # c = 1e-18: the multiplier is ~1e18, the slack of x >= 0 falls below eps * mu and
    # IPOPT moves the bound (slack_move); its point (-1e-18, 1e-18) has cost ~0 and
    # projected onto x >= 0 costs c^2, twice the constrained optimum. Measured: the
    # repeated solve reaches 1.0200500 c^2/2, the same under all six OpenBLAS kernels
    # (Haswell, SkylakeX, Zen, Sandybridge, Nehalem, Prescott); without it 2.0 c^2/2.
    c = 1e-18
    nlp, opts, x0, lb, ub, cost = _toy(c, 1e-18)
    res, stats, _, _ = ipopt.run_nlpsol("toy", nlp, opts, x0, lb, ub, cost_of=cost)
    assert stats.get("bound_retry") is True
    assert "solved again with the bounds held exactly" in res.message
    assert res.success and np.all(res.x >= lb)
    assert res.cost == cost(res.x)
    assert res.cost < 1.2 * (c * c / 2)              # measured 1.02 (2.0 without the repeat)
    assert res.nit == stats["iter_count"] > 0        # both solves counted


def test_a_point_inside_the_bounds_is_not_solved_again():
    # the optimum (-c, c) of the same problem with x free: no projection, one solve
    c = 1e-3
    nlp, opts, x0, _, ub, cost = _toy(c, 0.5)
    lb = np.array([-np.inf, -np.inf])
    res, stats, _, _ = ipopt.run_nlpsol("toy", nlp, opts, x0, lb, ub, cost_of=cost)
    assert "bound_retry" not in stats and "solved again" not in res.message
    assert res.success and res.cost < 1e-20          # measured ~1e-30 (exact optimum 0)


def _double_well(max_hessian_perturbation):
    """``min (x^2 - 1)^2`` from x = 0.1, where the Hessian 12 x^2 - 4 is negative: IPOPT's
    inertia correction needs a regularisation of about 4, so a ``max_hessian_perturbation``
    below that makes its step computation fail at the first iteration."""
    z = ca.MX.sym("z", 1)
    opts = ipopt.base_options(100, 1e-12, False)
    opts["ipopt"]["max_hessian_perturbation"] = max_hessian_perturbation
    return {"x": z, "f": (z[0] ** 2 - 1) ** 2}, opts, lambda v: float((v[0] ** 2 - 1) ** 2)


def test_a_failed_step_computation_is_solved_again_with_more_regularisation():
    nlp, opts, cost = _double_well(1e-3)
    x0, lb, ub = np.array([0.1]), np.array([-10.0]), np.array([10.0])
    res, stats, _, _ = ipopt.run_nlpsol("well", nlp, opts, x0, lb, ub, cost_of=cost)
    assert stats.get("step_retry") is True
    assert "IPOPT's step computation failed (Error_In_Step_Computation)" in res.message
    assert res.success and res.x[0] == pytest.approx(1.0, abs=1e-8)   # measured |x - 1| ~ 0
    assert res.cost < 1e-16 < cost(x0)


def test_a_step_failure_the_repeat_cannot_mend_returns_the_start(monkeypatch):
    # the repeat made as unable as the first (its allowance kept at 1e-3): both fail at
    # their first iteration; the result is the start, not IPOPT's pushed point
    monkeypatch.setattr(ipopt, "MAX_HESSIAN_PERTURBATION", 1e-3)
    nlp, opts, cost = _double_well(1e-3)
    x0, lb, ub = np.array([0.1]), np.array([-10.0]), np.array([10.0])
    res, stats, _, _ = ipopt.run_nlpsol("well", nlp, opts, x0, lb, ub, cost_of=cost)
    assert stats.get("step_retry") is True and not res.success
    assert res.solver_status == "Error_In_Step_Computation"
    assert res.cost <= cost(x0) and np.all(res.x >= lb) and np.all(res.x <= ub)

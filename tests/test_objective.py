"""Tests of freqid_casadi.core.objective: the (re, im) objective against plain complex numpy
(docs/style.md §1.2), the gauge maps, and the stage derivatives against finite differences and
CasADi's own AD."""

import itertools

import casadi as ca
import numpy as np
import pytest

from freqid_casadi.errors import OptionError, StructureError
from freqid_casadi.core.model import BASES, RationalDelayModel, Structure
from freqid_casadi.core.objective import (
    GAUGES, Parametrization, StageFunctions, rel_error_stats, relative_residual, stage_functions)

OMEGA = np.logspace(-1, 2, 60)                         # rad/s
OMEGA_REF = (0.5, 3.0, 20.0)                           # one per section, rad/s
COMBOS = list(itertools.product(GAUGES, BASES, (False, True)))
IDS = [f"{g}-{b.split('-')[0]}-{'int' if i else 'noint'}" for g, b, i in COMBOS]


def _param(gauge, basis, integrator):
    return Parametrization(Structure(3, integrator, True, basis), gauge, OMEGA_REF,
                           gain_ref=2.0, delay_max=0.05)


def _max_rel(actual, expected):
    """max |actual - expected| / max |expected| (entrywise arrays)."""
    return float(np.max(np.abs(actual - expected)) / np.max(np.abs(expected)))


@pytest.fixture(scope="module", params=COMBOS, ids=IDS)
def case(request):
    gauge, basis, integrator = request.param
    rng = np.random.default_rng(COMBOS.index(request.param))
    param = _param(gauge, basis, integrator)
    z = rng.uniform(0.3, 1.5, param.n_vars)
    # data: another model of the same structure, perturbed, so the residual is O(1)
    z_true = rng.uniform(0.3, 1.5, param.n_vars)
    response = (param.to_model(z_true).frequency_response(OMEGA)
                * (1 + 0.05 * (rng.standard_normal(OMEGA.size)
                               + 1j * rng.standard_normal(OMEGA.size))))
    weights = rng.uniform(0.2, 3.0, OMEGA.size)
    funcs = StageFunctions(param, OMEGA, response, weights)
    return dict(param=param, z=z, response=response, weights=weights, funcs=funcs)


def _expected_residual(case):
    g = case["param"].to_model(case["z"]).frequency_response(OMEGA)
    return np.sqrt(case["weights"]) * (case["response"] / g - 1.0)


# ------------------------------------------------------------------ formula vs complex numpy
def test_residual_pair_matches_complex_numpy(case):
    param, z, resp = case["param"], case["z"], case["response"]
    model = param.to_model(z)
    ratio = resp / model.frequency_response(OMEGA)                 # complex numpy
    re, im = param.ratio(z, OMEGA, (resp.real, resp.imag))
    assert np.max(np.abs((re + 1j * im) - ratio) / np.abs(ratio)) <= 1e-12
    re, im = param.residual_pair(z, OMEGA, (resp.real, resp.imag))
    # relative to |Phi/G_N| (the residual itself may be small at some points)
    assert np.max(np.abs((re + 1j * im) - (ratio - 1.0)) / np.abs(ratio)) <= 1e-12
    sw = np.sqrt(case["weights"])
    re, im = param.residual_pair(z, OMEGA, (resp.real, resp.imag), sw)
    assert np.max(np.abs((re + 1j * im) - sw * (ratio - 1.0)) / (sw * np.abs(ratio))) <= 1e-12
    np.testing.assert_allclose(relative_residual(model, OMEGA, resp), ratio - 1.0,
                               rtol=0, atol=1e-15 * np.max(np.abs(ratio)))


def test_to_beta_is_nonnegative_model(case):
    param, z = case["param"], case["z"]
    beta = param.to_beta(z)
    assert beta.shape == (param.structure.n_params,)
    np.testing.assert_allclose(param.from_beta(beta), z, rtol=1e-12, atol=1e-15)
    model = param.to_model(z)
    assert isinstance(model, RationalDelayModel)
    assert model.delay == pytest.approx(0.05 * z[0], rel=1e-15)
    assert model.is_stable() and model.is_minimum_phase()


def test_from_beta_inverts_to_beta(case):
    param, z = case["param"], case["z"]
    back = param.from_beta(param.to_beta(z))
    np.testing.assert_allclose(back, z, rtol=1e-12, atol=0)


def test_dc_gauge_zero_at_infinity():
    """p2 = 0 (a = 0 in the thesis form) takes the other branch of the dc -> beta map."""
    param = _param("dc", "second-order", True)
    z = np.array([0.4, 1.2, 0.0, 0.7, 1.1, 0.3, 0.9, 0.2, 0.5, 0.8, 0.6, 1.4, 0.0, 0.05])
    resp = np.exp(1j * OMEGA / 7.0) / (1 + 1j * OMEGA)
    beta = param.to_beta(z)
    assert beta[2] == 0.0 and beta[17] == 0.0                     # a[1] = 0 and b[3] = 0
    ratio = resp / param.to_model(z).frequency_response(OMEGA)
    re, im = param.ratio(z, OMEGA, (resp.real, resp.imag))
    assert np.max(np.abs((re + 1j * im) - ratio) / np.abs(ratio)) <= 1e-12
    np.testing.assert_allclose(param.from_beta(beta), z, rtol=1e-12, atol=1e-15)
    assert param.to_model(z).zeros().size == 5                    # one zero dropped to infinity


def test_parametrization_validation():
    s = Structure(2)
    with pytest.raises(OptionError, match=r"unknown gauge 'xyz'"):
        Parametrization(s, "xyz", (1.0, 2.0))
    with pytest.raises(StructureError, match=r"omega_ref needs one frequency per section: got 1 "
                                             r"for 2 sections"):
        Parametrization(s, "dc", (1.0,))
    for bad in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(OptionError, match=r"delay_max must be a finite number > 0"):
            Parametrization(s, "dc", (1.0, 2.0), delay_max=bad)
    p = Parametrization(s, "dc", (1.0, 2.0), delay_max=0.3)
    lb, ub = p.bounds()
    assert np.array_equal(lb, np.zeros(p.n_vars)) and ub[0] == 1.0 and np.all(np.isinf(ub[1:]))
    assert Parametrization(Structure(2, delay=False), "dc", (1.0, 2.0)).bounds()[1][0] == 0.0


def test_rel_error_stats():
    assert rel_error_stats([0.3, 0.4]) == (0.4, pytest.approx(np.sqrt(0.125), rel=1e-15))


# ------------------------------------------------------------------ StageFunctions
def test_stage_residual_matches_complex_numpy(case):
    funcs, z = case["funcs"], case["z"]
    r = funcs.residual(z)
    expected = _expected_residual(case)
    assert r.shape == (2 * OMEGA.size,) and funcs.n_points == OMEGA.size
    scale = np.sqrt(case["weights"]) * np.abs(expected / np.sqrt(case["weights"]) + 1.0)
    rc = r[:OMEGA.size] + 1j * r[OMEGA.size:]
    assert np.max(np.abs(rc - expected) / scale) <= 1e-12
    r2, _ = funcs.residual_jacobian(z)
    np.testing.assert_allclose(r2, r, rtol=1e-13, atol=1e-15)
    assert funcs.cost(z) == pytest.approx(float(r @ r), rel=1e-13)


def test_jacobian_matches_central_differences(case):
    funcs, z = case["funcs"], case["z"]
    _, jac = funcs.residual_jacobian(z)
    assert jac.shape == (2 * OMEGA.size, case["param"].n_vars)
    step = 1e-6
    fd = np.empty_like(jac)
    for k in range(z.size):
        dz = np.zeros_like(z)
        dz[k] = step
        fd[:, k] = (funcs.residual(z + dz) - funcs.residual(z - dz)) / (2 * step)
    for k in range(z.size):                                # column by column
        assert _max_rel(jac[:, k], fd[:, k]) <= 1e-6, f"column {k}"


def test_jacobian_matches_casadi_ad(case):
    funcs, z = case["funcs"], case["z"]
    zs = ca.MX.sym("z", case["param"].n_vars)
    jac_ad = ca.Function("jac_ad", [zs], [ca.jacobian(funcs.r_fun(zs), zs)])(z).full()
    _, jac = funcs.residual_jacobian(z)
    assert _max_rel(jac, jac_ad) <= 1e-10


def test_hessian_matches_casadi_ad(case):
    funcs, z = case["funcs"], case["z"]
    zs = ca.MX.sym("z", case["param"].n_vars)
    hess_expr, _ = ca.hessian(ca.sumsqr(funcs.r_fun(zs)), zs)
    hess_ad = ca.Function("hess_ad", [zs], [hess_expr])(z).full()
    hess = funcs.hessian(z)
    assert np.array_equal(hess, hess.T) or _max_rel(hess, hess.T) <= 1e-14
    assert _max_rel(hess, hess_ad) <= 1e-9
    assert _max_rel(funcs.hessian(z, exact=False), hess_ad) > 1e-6    # the check has teeth


def test_gauss_newton_hessian_and_gradient(case):
    funcs, z = case["funcs"], case["z"]
    r, jac = funcs.residual_jacobian(z)
    np.testing.assert_allclose(funcs.hessian(z, exact=False), 2 * jac.T @ jac,
                               rtol=1e-12, atol=1e-12 * np.max(np.abs(jac)) ** 2)
    cost, grad = funcs.gradient(z)
    assert cost == pytest.approx(float(r @ r), rel=1e-13)
    np.testing.assert_allclose(grad, 2 * jac.T @ r, rtol=1e-12,
                               atol=1e-12 * np.max(np.abs(jac)) * np.max(np.abs(r)))


def test_gradient_matches_casadi_ad(case):
    funcs, z = case["funcs"], case["z"]
    zs = ca.MX.sym("z", case["param"].n_vars)
    grad_expr = ca.gradient(ca.sumsqr(funcs.r_fun(zs)), zs)
    grad_ad = ca.Function("grad_ad", [zs], [grad_expr])(z).full()
    assert _max_rel(funcs.gradient(z)[1], grad_ad.reshape(-1)) <= 1e-10


def test_gauss_newton_hessian_is_positive_semidefinite_and_cached():
    param = _param("raw", "second-order", False)
    rng = np.random.default_rng(7)
    z = rng.uniform(0.3, 1.5, param.n_vars)
    resp = param.to_model(rng.uniform(0.3, 1.5, param.n_vars)).frequency_response(OMEGA)
    funcs = stage_functions(param, OMEGA, resp)
    assert isinstance(funcs, StageFunctions)
    lam = np.linalg.eigvalsh(funcs.hessian(z, exact=False))
    assert lam.min() >= -1e-10 * lam.max()
    # the exact Hessian of this far-from-optimal point has negative curvature
    assert np.linalg.eigvalsh(funcs.hessian(z)).min() < -1e-6 * lam.max()
    # evaluation cache: a new z gives new values
    h1 = funcs.hessian(z)
    h2 = funcs.hessian(z * 1.01)
    assert not np.allclose(h1, h2)
    np.testing.assert_array_equal(funcs.hessian(z), h1)


@pytest.mark.parametrize("basis", BASES)
@pytest.mark.parametrize("integrator", [False, True])
def test_affine_derivatives_match_casadi_map(basis, integrator):
    """The dc gauge's numpy path (sections affine in the variables) and CasADi's AD of the
    per-point formula mapped over the points give the same pieces and derivatives."""
    param = _param("dc", basis, integrator)
    rng = np.random.default_rng(11)
    z = rng.uniform(0.3, 1.5, param.n_vars)
    resp = param.to_model(rng.uniform(0.3, 1.5, param.n_vars)).frequency_response(OMEGA)
    weights = rng.uniform(0.2, 3.0, OMEGA.size)
    fast = StageFunctions(param, OMEGA, resp, weights)
    ref = StageFunctions(param, OMEGA, resp, weights, derivatives="casadi-map")
    assert fast.derivatives == "affine" and ref.derivatives == "casadi-map"
    for a, b in zip(fast.residual_jacobian(z), ref.residual_jacobian(z)):
        assert _max_rel(a, b) <= 1e-13
    assert _max_rel(fast.gradient(z)[1], ref.gradient(z)[1]) <= 1e-13
    assert _max_rel(fast.hessian(z), ref.hessian(z)) <= 1e-13


@pytest.mark.parametrize("derivatives", ["affine", "casadi-map"])
def test_blockwise_products_match_whole_arrays(derivatives, monkeypatch):
    """The Hessian, column norms and Jacobian are products over the points formed in blocks
    of ``_BLOCK_POINTS`` (one block: the whole-array product itself). Blocks of 7 points
    (the last one short) against one block: the Jacobian bit for bit, the Hessians and
    column norms measured 3e-16 relative; bound 1e-13."""
    import importlib

    deriv = importlib.import_module("freqid_casadi.core.derivatives")
    param = _param("dc" if derivatives == "affine" else "b1", "second-order", True)
    rng = np.random.default_rng(12)
    z = rng.uniform(0.3, 1.5, param.n_vars)
    resp = param.to_model(rng.uniform(0.3, 1.5, param.n_vars)).frequency_response(OMEGA)
    weights, pw = rng.uniform(0.2, 3.0, OMEGA.size), rng.uniform(0.0, 1.0, OMEGA.size)

    def products():
        f = StageFunctions(param, OMEGA, resp, weights, derivatives=derivatives)
        return (f.residual_jacobian(z)[1], f.hessian(z), f.hessian(z, exact=False),
                f.hessian(z, point_weights=pw), f.column_norms(z))

    whole = products()
    monkeypatch.setattr(deriv, "_BLOCK_POINTS", 7)
    blocks = products()
    np.testing.assert_array_equal(blocks[0], whole[0])
    for a, b in zip(blocks[1:], whole[1:]):
        assert _max_rel(a, b) <= 1e-13


@pytest.mark.parametrize("gauge", ["dc", "b1"])
def test_residual_and_cost_from_the_pieces_match_the_mx_residual(gauge, monkeypatch):
    """Above ``_PIECES_COST_POINTS`` points the residual and IPOPT's objective come from
    the derivative pieces instead of the MX residual ``r_fun``. Forced on 60 points:
    measured 9e-16 (residual, relative to its largest entry) and 2e-16 (cost); bound
    1e-13."""
    import importlib

    deriv = importlib.import_module("freqid_casadi.core.derivatives")
    param = _param(gauge, "second-order", True)
    rng = np.random.default_rng(13)
    z = rng.uniform(0.3, 1.5, param.n_vars)
    resp = param.to_model(rng.uniform(0.3, 1.5, param.n_vars)).frequency_response(OMEGA)
    weights = rng.uniform(0.2, 3.0, OMEGA.size)
    mx = StageFunctions(param, OMEGA, resp, weights)
    r_mx, cost_mx = mx.residual(z), mx.nlp_cost(z)
    np.testing.assert_array_equal(r_mx, np.asarray(mx.r_fun(z)).reshape(-1))
    monkeypatch.setattr(deriv, "_PIECES_COST_POINTS", 0)
    pieces = StageFunctions(param, OMEGA, resp, weights)
    assert _max_rel(pieces.residual(z), r_mx) <= 1e-13
    assert abs(pieces.nlp_cost(z) - cost_mx) <= 1e-13 * cost_mx
    assert pieces.nlp_cost(z) == pieces.gradient(z)[0]


@pytest.mark.parametrize("derivatives", ["affine", "casadi-map"])
def test_projected_fraction_without_the_jacobian(derivatives, monkeypatch):
    """StageFunctions.projected_fraction (a blockwise QR of [J_free / ||J_j|| | r], no
    Jacobian formed) is the stationarity test's ``projected_fraction(r, J, free)`` (an SVD
    of the Jacobian): all variables free and some held, in one block and in blocks of 7
    points. Measured 2e-15 relative; bound 1e-12."""
    import importlib

    from freqid_casadi.solvers.termination import projected_fraction

    deriv = importlib.import_module("freqid_casadi.core.derivatives")
    param = _param("dc" if derivatives == "affine" else "b1", "second-order", True)
    rng = np.random.default_rng(5)
    z = rng.uniform(0.3, 1.5, param.n_vars)
    resp = param.to_model(rng.uniform(0.3, 1.5, param.n_vars)).frequency_response(OMEGA)
    funcs = StageFunctions(param, OMEGA, resp, rng.uniform(0.2, 3.0, OMEGA.size),
                           derivatives=derivatives)
    r, jac = funcs.residual_jacobian(z)
    held = np.ones(param.n_vars, bool)
    held[[1, 4, 9]] = False
    for free in (np.ones(param.n_vars, bool), held):
        expected = projected_fraction(r, jac, free)
        assert 0.0 < expected < 1.0
        assert abs(funcs.projected_fraction(z, free) - expected) <= 1e-12 * expected
        monkeypatch.setattr(deriv, "_BLOCK_POINTS", 7)
        assert abs(funcs.projected_fraction(z, free) - expected) <= 1e-12 * expected
        monkeypatch.setattr(deriv, "_BLOCK_POINTS", 8192)
    assert funcs.projected_fraction(z, np.zeros(param.n_vars, bool)) == 0.0


def test_affine_derivatives_need_the_dc_gauge():
    with pytest.raises(OptionError, match="dc"):
        StageFunctions(_param("b1", "second-order", False), OMEGA, np.ones(OMEGA.size),
                       derivatives="affine")
    with pytest.raises(OptionError, match="unknown derivatives"):
        StageFunctions(_param("dc", "second-order", False), OMEGA, np.ones(OMEGA.size),
                       derivatives="fd")


def test_damping_constraints_and_projection():
    """c1^2 - 4 zeta_min^2 c2 >= 0 <=> zeta >= zeta_min for 1 + c1 x + c2 x^2; projection
    only raises c1, and a zero at infinity (c2 = 0) is admissible."""
    param = _param("dc", "second-order", False)
    z = np.array([0.3, 1.0] + [1.0, 0.001, 4.0, 0.5] + [0.0, 0.0, 0.25, 0.005]
                 + [2.0, 3.0, 1.0, 0.02])
    zeta_min = 0.01
    g = param.damping_constraints(zeta_min)
    zs = param.project_damping(z, zeta_min)
    beta = param.to_beta(zs)
    s = RationalDelayModel(param.structure, beta).sections()
    finite = s[:, 0] > 0                                    # the zero at infinity has a = 0
    assert np.all(s[finite, 1] / np.sqrt(s[finite, 0]) >= zeta_min * (1 - 1e-12))
    assert np.all(s[:, 4] / np.sqrt(s[:, 3]) >= zeta_min * (1 - 1e-12))
    assert np.all(g(zs) >= 0) and np.any(g(z) < 0)
    assert np.all(zs >= z) and np.count_nonzero(zs != z) == 2       # two raised c1's
    zsym = ca.SX.sym("z", param.n_vars)
    gf = ca.Function("g", [zsym], [g(zsym)])
    np.testing.assert_allclose(gf(z).full().ravel(), g(z), rtol=1e-15)
    with pytest.raises(OptionError, match="dc"):
        _param("b1", "second-order", False).damping_constraints(0.01)
    with pytest.raises(OptionError, match="second-order"):
        _param("dc", "first-order", False).damping_constraints(0.01)


@pytest.mark.parametrize("p", [4.0, 64.0])
@pytest.mark.parametrize("gauge", ["dc", "raw"])
def test_pnorm_derivatives_match_casadi_ad(p, gauge):
    """The structured gradient/Hessian of the p-norm stand-in for the max error against
    CasADi's AD of its log-sum-exp form."""
    from freqid_casadi.core.objective import PNormFunctions

    param = _param(gauge, "second-order", True)
    rng = np.random.default_rng(5)
    z = rng.uniform(0.3, 1.5, param.n_vars)
    resp = (param.to_model(rng.uniform(0.3, 1.5, param.n_vars)).frequency_response(OMEGA)
            * (1 + 0.05 * rng.standard_normal(OMEGA.size)))
    funcs = StageFunctions(param, OMEGA, resp, rng.uniform(0.5, 2.0, OMEGA.size))
    r0 = funcs.residual(z)
    m = OMEGA.size
    s = float(np.max(r0[:m] ** 2 + r0[m:] ** 2))
    pn = PNormFunctions(funcs, p, s)
    zs = ca.MX.sym("z", param.n_vars)
    r = funcs.r_fun(zs)
    f = ca.logsumexp(0.5 * p * ca.log((r[:m] ** 2 + r[m:] ** 2) / s)) / p
    hess_expr, grad_expr = ca.hessian(f, zs)
    fun = ca.Function("pn", [zs], [f, grad_expr, hess_expr])
    f_ad, g_ad, h_ad = (np.array(v.full()) for v in fun(z))
    value, grad = pn.gradient(z)
    assert value == pytest.approx(float(f_ad.ravel()[0]), rel=1e-12)
    assert _max_rel(grad, g_ad.ravel()) <= 1e-10
    assert _max_rel(pn.hessian(z), h_ad) <= 1e-9

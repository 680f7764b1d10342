"""The speed changes of issue 30 keep the numbers: each faster path gives the same values
bit for bit as the path it replaced, and a fit's stages no longer stay alive."""

import dataclasses
import gc
import os
import subprocess
import sys

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.core.derivatives import StageFunctions
from freqid_casadi.core.objective import Parametrization, stage_functions
from freqid_casadi.solvers.common import CALLBACK_COST_POINTS, StageProblem
from freqid_casadi.solvers.ipopt import solve_stage
from freqid_casadi.solvers.termination import Termination


def _stage(m, ns=2, derivatives=None):
    data = fc.systems.G_A(np.logspace(-2, 3, m))
    wr = tuple(np.logspace(0, 3, ns))
    param = Parametrization(fc.Structure(ns, True, True), "dc", wr,
                            abs(data.response[0]) * data.omega[0], 0.1)
    z0 = np.concatenate([[0.08, 1.0]] + [param.new_section(w, 0.01, 1.1 * w, 0.02, w)
                                         for w in wr])
    return param, stage_functions(param, data.omega, data.response,
                                  derivatives=derivatives), z0


def test_nlp_cost_is_the_mx_objective_bit_for_bit():
    import casadi as ca

    param, funcs, z0 = _stage(300)
    z = ca.MX.sym("z", param.n_vars)
    mx = ca.Function("f", [z], [ca.sumsqr(funcs.r_fun(z))])
    for k in range(3):
        x = z0 * (1.0 + 0.01 * k)
        assert funcs.nlp_cost(x) == float(mx(x))


@pytest.mark.parametrize("integrator, charts, scaled, weighted", [
    (True, (), True, False), (-2, ((0, 2), (1, 0)), True, True), (False, (), False, True)])
def test_stages_share_a_residual_template_with_the_numbers_of_their_own(integrator, charts,
                                                                         scaled, weighted):
    # two stages of one structure with other references and data share one kept formula;
    # each stage's MX residual gives the numpy residual's numbers bit for bit
    from freqid_casadi.core import derivatives

    structure = fc.Structure(2, integrator, True)
    omega = np.logspace(-1, 2, 120)
    built = []
    for k, wr in enumerate(((1.0, 30.0), (2.5, 11.0))):
        data = fc.systems.G_A(omega * (1.0 + 0.1 * k))
        weights = np.linspace(1.0, 3.0, omega.size) if weighted else None
        param = Parametrization(structure, "dc", wr, 0.3 + k, 0.05 * (k + 1), scaled=scaled,
                                charts=charts)
        funcs = stage_functions(param, data.omega, data.response, weights=weights)
        z = np.concatenate([[0.4, 1.1]] + [param.new_section(w, 0.02, 1.2 * w, 0.05, w)
                                            for w in wr])
        want = np.concatenate(param.residual_pair(
            z, data.omega, (data.response.real, data.response.imag),
            None if weights is None else np.sqrt(weights)))
        np.testing.assert_array_equal(np.asarray(funcs.r_fun(z)).ravel(), want)
        built.append(derivatives.residual_template(param, omega.size))
    assert built[0] is built[1]


def test_a_stage_solved_with_the_cost_callback_ends_where_the_mx_objective_does():
    param, funcs, z0 = _stage(CALLBACK_COST_POINTS)
    lb, ub = param.bounds()
    pb = StageProblem.from_stage_functions(funcs, lb, ub)
    assert pb.nlp_cost is not None                   # at this many points: the callback
    term = Termination(ftol=0.0, noise_factor=0.0, polish_steps=0)
    a = solve_stage(pb, z0, max_iter=15, termination=term)
    b = solve_stage(dataclasses.replace(pb, nlp_cost=None), z0, max_iter=15,
                    termination=term)
    assert a.nit == b.nit == 15
    np.testing.assert_array_equal(a.x, b.x)
    assert a.cost == b.cost
    assert a.cost < pb.eval_cost(z0)                  # (it did move)


@pytest.mark.parametrize("derivatives", ["affine", "casadi-map"])
def test_hessian_scratch_arrays_do_not_leak_between_calls(derivatives):
    _, funcs, z0 = _stage(200, derivatives=derivatives)
    z1 = z0 * 1.01
    h0, g0, c0 = funcs.hessian(z0), funcs.hessian(z0, exact=False), funcs.column_norms(z0)
    saved = h0.copy(), g0.copy(), c0.copy()
    h1 = funcs.hessian(z1)
    funcs.column_norms(z1)
    for a, b in zip((h0, g0, c0), saved):          # earlier results are not overwritten
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(funcs.hessian(z0), saved[0])
    assert not np.array_equal(h1, saved[0])
    # what is kept per point (|sqrt_w q|^2, shared by both) follows the point: the values
    # at z1 reached from z0 are a fresh stage's
    _, fresh, _ = _stage(200, derivatives=derivatives)
    np.testing.assert_array_equal(h1, fresh.hessian(z1))
    funcs.column_norms(z0)
    np.testing.assert_array_equal(funcs.column_norms(z1), fresh.column_norms(z1))
    # against the products written without scratch arrays
    funcs._eval(z0)
    lg, sq = funcs._L, funcs._sq
    a = sq.real ** 2 + sq.imag ** 2
    np.testing.assert_array_equal(c0, np.sqrt((lg.real ** 2 + lg.imag ** 2) @ a))
    y = lg * a
    gn = lg.view(float) @ y.view(float).T
    np.testing.assert_array_equal(g0, 2.0 * ((gn + gn.T) / 2.0))
    assert np.all(np.isfinite(h0)) and np.allclose(h0, h0.T)


def test_state_space_zeros_are_python_controls_bit_for_bit():
    import control as ct

    from freqid_casadi.baselines import vector_fitting

    data = fc.systems.G_B()
    for n in (3, 6, 10):
        m = vector_fitting(data, n)
        ref = np.asarray(ct.ss(m.A, m.B, m.C, [[m.D]]).zeros(), complex)
        got = m.zeros()
        assert got.shape == ref.shape and got.size > 0
        np.testing.assert_array_equal(np.sort_complex(got), np.sort_complex(ref))


def test_a_fits_stages_do_not_stay_alive():
    # each stage's StageFunctions (O(n M) arrays) used to be held by a reference cycle
    # (a callback class made per stage) until the next garbage collection
    data = fc.systems.G_A(np.logspace(-2, 3, 300))
    gc.collect()
    gc.disable()
    try:
        fc.fit(data, n_sections=2, integrator=True)
        alive = sum(isinstance(o, StageFunctions) for o in gc.get_objects())
    finally:
        gc.enable()
    assert alive <= 1


_FAULTS = r"""
import resource, numpy as np
from freqid_casadi._malloc import heap_kept
def faults():
    f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(200):
        a = np.ones(2 ** 17)            # 1 MiB, above glibc's frozen 128 KiB mmap threshold
        del a
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0
before = faults()
with heap_kept():
    during = faults()
after = faults()
print(before, during, after)
"""


def _with_dask_trim(code):
    """What ``code`` prints in a fresh interpreter whose environment fixes the trim
    threshold as Dask's nanny does (and leaves the mmap threshold free)."""
    env = dict(os.environ, MALLOC_TRIM_THRESHOLD_="65536")
    env.pop("MALLOC_MMAP_THRESHOLD_", None)
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, check=True).stdout


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_heap_kept_stops_the_page_faults_of_a_fixed_trim_threshold_and_restores_it():
    # Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536: every 1 MiB array is
    # then mapped afresh (256 page faults each, about 51 000 for 200 arrays); kept, the
    # heap re-uses the same pages (a few hundred faults at most), and after the block the
    # environment's setting is back
    before, during, after = map(int, _with_dask_trim(_FAULTS).split())
    assert before > 40_000 and after > 40_000
    assert during < 2_000


_RETURNED = r"""
import numpy as np
from freqid_casadi._malloc import heap_kept
def rss():
    return int(open("/proc/self/statm").read().split()[1]) * 4096
out = []
for mib in (8, 200):
    with heap_kept():
        arrays = [np.ones(1 << 17) for _ in range(mib)]    # 1 MiB each, in the heap
        del arrays[::2]                                     # holes: free, not the top
        inside = rss()
    out.append((inside - rss()) // (1 << 20))              # returned at the block's end
    del arrays
print(*out)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's heap")
def test_heap_kept_returns_the_free_heap_only_above_what_a_fit_may_keep():
    # a fit leaves a few MiB of free heap: returned after every fit, the next one faulted
    # it back in (4-6 % of its CPU); above 32 MiB it goes back to the system (measured: 0
    # of 4 MiB of holes returned, 101 of 100 MiB)
    from freqid_casadi import _malloc

    small, large = map(int, _with_dask_trim(_RETURNED).split())
    assert small <= 1
    assert large >= 80
    assert _malloc._free_heap(object()) is None        # no mallinfo2: always returned


def test_single_threaded_blas_limits_every_blas_and_restores_it(monkeypatch):
    # the limiter reuses one library scan (1.6 ms each, measured) and scans again after an
    # import; either way every loaded BLAS runs one thread inside and its own count after
    import sys

    from threadpoolctl import threadpool_info, threadpool_limits

    from freqid_casadi import _threads

    def counts():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    with threadpool_limits(limits=2, user_api="blas"):      # two: the limit shows
        before = counts()
        assert before and before == [2] * len(before)
        with _threads.single_threaded_blas():
            assert counts() == [1] * len(before)
            first = _threads._blas_controller()
        assert counts() == before
        assert _threads._blas_controller() is first                       # kept
        monkeypatch.setitem(sys.modules, "freqid_test_new_module", sys)   # an import
        assert _threads._blas_controller() is not first                   # scanned again
        limiter = _threads.single_threaded_blas()                         # a worker's hold
        assert counts() == [1] * len(before)
        limiter.restore_original_limits()
        assert counts() == before


def test_bounds_only_solve_takes_one_second_order_correction(monkeypatch):
    # without constraints a second-order correction re-solves the rejected step's own
    # system, and IPOPT's default repeats that identical attempt up to max_soc = 4 times
    # (an objective evaluation and a back-solve each). One attempt must give IPOPT's
    # default path bit for bit with fewer evaluations; a constrained NLP keeps the default.
    import casadi as ca

    from freqid_casadi.solvers.ipopt import solve_least_squares
    from freqid_casadi.solvers.termination import Termination

    param, funcs, z0 = _stage(300, 4)
    lb, ub = param.bounds()
    term = Termination(ftol=0.0, noise_factor=0.0, polish_steps=0)   # run to max_iter
    ours = solve_least_squares(funcs, z0, lb, ub, max_iter=120, termination=term)
    ipopt = solve_least_squares(funcs, z0, lb, ub, max_iter=120, termination=term,
                                ipopt_options={"max_soc": 4})
    assert ours.nit == ipopt.nit == 120
    np.testing.assert_array_equal(ours.x, ipopt.x)
    assert ours.cost == ipopt.cost
    # measured: 218 evaluations of the objective against 317 (IPOPT's default)
    assert ours.nfev < 0.85 * ipopt.nfev, (ours.nfev, ipopt.nfev)

    seen, nlpsol = [], ca.nlpsol
    monkeypatch.setattr(ca, "nlpsol", lambda name, plugin, nlp, opts: (
        seen.append((nlp.get("g") is not None, opts["ipopt"].get("max_soc"))),
        nlpsol(name, plugin, nlp, opts))[1])
    solve_least_squares(funcs, z0, lb, ub, max_iter=5, termination=term,
                        constraints=lambda z: z[2:4])
    solve_least_squares(funcs, z0, lb, ub, max_iter=5, termination=term)
    assert seen == [(True, None), (False, 1)]

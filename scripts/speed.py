"""Speed benchmark of issue 30: the package against scikit-rf's vector fitting and against
the numerical floor of its own iterations, in one run.

Usage::

    python scripts/speed.py [--out results] [--repeat 3] [--parts fits,iteration,...]
                            [--timeout 240]

Parts (all by default):

``fits``
    The measured sets of the repository (the actuator's H1 estimate, 166 points, 1-3
    sections with a delay; the DaISy robot arm, 101 points, 1, 3 and 5 sections) and of
    the corpus (``fc.systems.measured``: a VNA resonator, 401 points, 2 sections; an
    active 190 GHz two-port, 801 points, 3 sections; a ring-slot resonator, 101 points, 2
    sections; pyuff's impact accelerance, 1000 points, 3 sections): the
    fits with ``start="sequential"`` (the thesis's loop), ``start="rational"`` and
    ``start="best"`` (the default of ``fit`` and the CLI), and the default with
    ``n_jobs=2`` (the fits it compares, the integrator's contenders and both gain signs,
    in 2 forked workers; its CPU seconds include theirs), ``start="rational"`` and the
    default with the default fit's k and gain sign passed (``integrator=k,
    gain_sign=...``: the cost of the automatic choices), beside scikit-rf's
    ``VectorFitting`` of the same order (2 poles per section) on the same data (on one
    BLAS thread, as the package's fits), with each model's max relative error.
``iteration``
    One 5-section stage at 500 and 50 000 points: the seconds of one whole IPOPT iteration
    of the package (pairs of capped solves run back to back, each pair's difference of
    times over its difference of iteration counts; the median over the pairs, 15 pairs at
    500 points) against the floor: the stage's own numerical work timed in
    numpy beside it (the residual, the Jacobian, its Gauss-Newton product ``J^T J``, the
    exact Hessian and a dense solve of that size; one of each per iteration). Beside it,
    IPOPT's own cost per iteration on an NLP of the same size without Python callbacks (a
    dense 22-variable problem in CasADi's SX, bounded): what no change of the package's
    evaluations can remove.
``layers``
    Where a default fit's time goes: its IPOPT solves, their iterations and seconds by the
    layer of the pipeline that ran them (the rational start's polish, the sequential loop,
    the h = 0 candidates, the rescues, the resolution guard's floored refit, the delay
    hold's refits, the zeros="free" alternative), the number of fits the automatic
    integrator ran, and the time outside IPOPT (vector fittings, diagnostics, covariance).
``fixed``
    Fixed costs per fit (profiled, cumulative seconds of the named functions): problem
    construction (stage functions, ``nlpsol``), the rational start, candidate bookkeeping,
    diagnostics, covariance.
``large``
    200 000 points at 2 sections (example A's system): one ``fit`` with its integrator
    (``integrator=True``) in a fresh subprocess, its time and peak memory (``ru_maxrss``),
    then the arrays' own peak (``tracemalloc``) from a second fit (tracemalloc slows every
    allocation, so the timed fit runs without it), then the default fit
    (``integrator="auto"``, its contenders settled on a subset of the points).
``sweep``
    ``sweep(G_A(), 2:40:2, integrator=True)``.
``survey``
    A stabilization survey (:func:`~freqid_casadi.modal.survey.stabilization`) of 16
    channels x 1000 points (the beam of ``scripts/modal_benchmark.py``) over orders
    2:40:2, in a subprocess with a time limit.
``batch``
    128 FRFs (4 sections, 400 points, as ``scripts/batch_benchmark.py``) by
    ``fit_many`` with 1 and 2 local processes and, if Dask is installed, on a local Dask
    cluster of 1 and of 2 single-threaded workers: ``--repeat`` pairs of each (1, then 2,
    back to back), the median of the pairs' speed-ups (one pair varied 1.78 .. 1.98 between
    runs on the 2-core machine).

The whole run holds BLAS at one thread, as every fit of the package runs (vector fitting
and the numpy floor then do the same single-threaded work). The machine (2 cores) is shared
with other engineers: absolute times are noisy. Every
single-process time is the median of ``--repeat`` runs, the CPU seconds of this process
(``time.process_time``) are given beside the wall time, and the report's conclusions are
ratios measured in the same run. The load average is recorded before and after each part.
Writes ``<out>/speed.md`` (first line: this command) and ``<out>/speed.json``.
"""

import argparse
import cProfile
import importlib
import json
import os
import platform
import pstats
import resource
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import freqid_casadi as fc  # noqa: E402
from freqid_casadi.report.environment import computed_on_lines, environment  # noqa: E402
from freqid_casadi.report.folder import atomic_write_text  # noqa: E402

PARTS = ("fits", "iteration", "layers", "fixed", "large", "sweep", "survey", "batch")
FIT_SETS = {"actuator": (1, 2, 3), "robot arm": (1, 3, 5), "resonator_36mm_s21": (2,),
            "tx190_s21": (3,), "ring_slot_s11": (2,), "impact_1": (3,)}
STARTS = ("sequential", "rational", "best")
#: (start, n_jobs, given) of the fits part: each start, the default with the fits it
#: compares in 2 worker processes (CPU seconds then include the workers'), and
#: start="rational" and the default with the default fit's k and gain sign passed
#: (``given``: what the automatic choices of ``integrator`` and ``gain_sign`` cost)
VARIANTS = (tuple((start, 1, False) for start in STARTS)
            + (("best", 2, False), ("rational", 1, True), ("best", 1, True)))
ITER_SECTIONS, ITER_POINTS = 5, (500, 50_000)
#: pairs of capped solves per iteration measurement at 500 points (cheap: 70 ms a pair)
ITER_REPEAT = 15
#: Vector fittings timed per row of the fits part (the median is the row's VF time).
VF_REPEAT = 15
LARGE_POINTS, LARGE_SECTIONS = 200_000, 2
N_BATCH = 128


def _median(values):
    return float(np.median(np.asarray(values, float)))


def _children_cpu():
    """CPU seconds of this process's finished child processes (a fit's forked workers)."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _timed(fn, repeat):
    """(result of the last call, median wall s, median CPU s) of ``repeat`` calls."""
    walls, cpus = [], []
    for _ in range(repeat):
        t0, c0, k0 = time.perf_counter(), time.process_time(), _children_cpu()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0 + _children_cpu() - k0)   # + worker processes
    return out, _median(walls), _median(cpus)


# ----------------------------------------------------------------------------- fits


def measured_sets():
    """{name: FrequencyData} of the repository's measured sets (as the measured study)."""
    from freqid_casadi.core.data import FrequencyData
    from freqid_casadi.studies.measured import actuator_frf

    est = fc.experiment.robot_arm()
    act = actuator_frf().data
    sets = {"actuator": FrequencyData(act.omega, act.response, "actuator", unit=act.unit),
            "robot arm": est.data}
    return {**sets, **{name: fc.systems.measured(name) for name in FIT_SETS
                       if name not in sets}}


def part_fits(repeat):
    from freqid_casadi.baselines import skrf_vector_fitting
    from freqid_casadi.core.metrics import relative_error

    rows = []
    for name, data in measured_sets().items():
        for n in FIT_SETS[name]:
            # on one BLAS thread (main() holds the limit for the run), as every fit of the
            # package runs: with the default threads its time swung 1-5x between runs with
            # the machine's load (6.7 -> 33 ms on the robot arm at order 12)
            # median of VF_REPEAT (a few ms each): with 3, one row's VF time moved 3.8 ->
            # 6.9 ms between runs of the same code, and the ratios' median with it
            model, wall, cpu = _timed(lambda: skrf_vector_fitting(data, 2 * n),
                                      max(repeat, VF_REPEAT))
            err = relative_error(model, data)
            vf = {"wall": wall, "cpu": cpu, "max_rel_error": float(err.max)}
            chosen = {}
            for start, jobs, given in VARIANTS:
                kw = dict(n_sections=n, delay=True, start=start, n_jobs=jobs,
                          **(chosen if given else {}))
                res, wall, cpu = _timed(lambda: fc.fit(data, **kw), repeat)
                if (start, jobs, given) == ("best", 1, False):    # the default's choices
                    chosen = dict(integrator=int(res.model.origin_order),
                                  gain_sign="positive" if res.model.structure.gain_sign > 0
                                  else "negative")
                label = _label(start, jobs, given)
                if jobs > 1:
                    # after forked workers exit, OpenBLAS's threads in this process spin for
                    # ~0.1 s: measured, the next vector fitting took 2-3x its time (CPU and
                    # wall); the next timed call waits them out
                    time.sleep(1.0)
                rows.append({"data": name, "n_points": int(data.n_points), "n_sections": n,
                             "order": 2 * n, "start": label, "wall": wall, "cpu": cpu,
                             "nit": int(res.nit), "max_rel_error": float(res.max_rel_error),
                             "success": bool(res.success), "vf": vf,
                             "ratio_wall": wall / vf["wall"], "ratio_cpu": cpu / vf["cpu"]})
                print(f"  fits: {name} {n} {label}: {wall:.3f} s, VF {vf['wall'] * 1e3:.1f} ms",
                      file=sys.stderr)
    return rows


def _label(start, jobs, given):
    """The row label of a fits variant (:data:`VARIANTS`)."""
    return (start + (f", {jobs} jobs" if jobs > 1 else "")
            + (", k and sign given" if given else ""))


# ----------------------------------------------------------------------------- iteration


def _stage(n_points, n_sections):
    from freqid_casadi.core.objective import Parametrization

    data = fc.systems.G_A(np.logspace(-2, 3, n_points))
    gain0 = abs(data.response[0]) * data.omega[0]
    wr = tuple(np.logspace(0, 3, n_sections))
    param = Parametrization(fc.Structure(n_sections, True, True), "dc", wr, gain0, 0.1)
    z0 = np.concatenate([[0.08, 1.0]] + [param.new_section(w, 0.01, 1.1 * w, 0.02, w)
                                         for w in wr])
    return data, param, z0


def _floor(funcs, param, data, z, repeat):
    """CPU seconds of the stage's own numerical work at ``z`` (median of ``repeat``)."""
    omega, pair = data.omega, (data.response.real, data.response.imag)

    def resid():
        return param.residual_pair(z, omega, pair)

    def jac():
        funcs._key = None                       # a new point: the pieces are recomputed
        return funcs.residual_jacobian(z)

    _, J = funcs.residual_jacobian(z)
    H = funcs.hessian(z)
    g = funcs.gradient(z)[1]
    items = {"residual": resid, "jacobian": jac, "jtj": lambda: J.T @ J,
             "hessian": lambda: funcs.hessian(z),
             "solve": lambda: np.linalg.solve(H + np.eye(g.size), g)}
    out = {}
    for key, fn in items.items():
        fn()
        n = max(1, int(0.05 / max(_timed(fn, 1)[2], 1e-6)))
        out[key] = _median([_timed(fn, n)[2] for _ in range(repeat)])
    out["floor"] = out["residual"] + out["jacobian"] + out["hessian"] + out["solve"]
    return out


def _ipopt_alone(n, repeat):
    """CPU seconds per IPOPT iteration on a dense, bounded ``n``-variable NLP whose
    functions are CasADi SX (no Python callback; its evaluations cost microseconds):
    IPOPT's own work per iteration at that size, measured as the stage's iteration is
    (pairs of capped solves, :func:`_paired`, after as many pairs not counted; with medians
    of 3 solves of each cap, two readings of the same NLP in one run read 0.41 and 0.24
    ms)."""
    import types

    import casadi as ca

    from freqid_casadi.solvers.ipopt import BOUNDS_ONLY_MAX_SOC

    x = ca.SX.sym("x", n)
    a = np.random.default_rng(0).standard_normal((n, n)) / np.sqrt(n)
    f = (ca.sumsqr(x - ca.DM(np.linspace(0.5, 2.0, n)))
         + 10.0 * ca.sumsqr(x[1:] - x[:-1] ** 2) + 0.1 * ca.sumsqr(ca.mtimes(a, x)) ** 1.5)
    lo, hi = 3, 25
    # the package's IPOPT options for an NLP of bounds only (one second-order correction);
    # the solvers are built before the clock
    solvers = {k: ca.nlpsol("alone", "ipopt", {"x": x, "f": f}, {
        "print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "max_iter": k,
                                       "tol": 1e-30, "acceptable_iter": 0,
                                       "max_soc": BOUNDS_ONLY_MAX_SOC}}) for k in (lo, hi)}

    def solve(k):
        solvers[k](x0=-np.ones(n), lbx=-10.0, ubx=10.0)
        return types.SimpleNamespace(nit=int(solvers[k].stats()["iter_count"]))

    # warm-up pairs, not counted: in a fresh process the first 6-7 pairs took 0.46-0.50 ms
    # per iteration, the rest 0.24 (and the median of 15 pairs read 0.26 where it included them)
    _paired(solve, lo, hi, ITER_REPEAT)
    return _paired(solve, lo, hi, max(repeat, ITER_REPEAT))[1][1]


def _paired(solve, lo, hi, repeat):
    """Seconds per iteration of ``solve``: ``repeat`` pairs of capped solves (``lo`` then
    ``hi`` iterations, back to back, so that a slow spell of the shared machine falls on
    both), each pair's difference over the difference of its iteration counts; returns
    ``((last lo result, last hi result), (median wall, median CPU, [CPU of each pair]))``.
    The construction and the first iterations cancel in each difference."""
    walls, cpus = [], []
    for _ in range(repeat):
        r_lo, w_lo, c_lo = _timed(lambda: solve(lo), 1)
        r_hi, w_hi, c_hi = _timed(lambda: solve(hi), 1)
        d_it = max(r_hi.nit - r_lo.nit, 1)
        walls.append((w_hi - w_lo) / d_it)
        cpus.append((c_hi - c_lo) / d_it)
    return (r_lo, r_hi), (_median(walls), _median(cpus), cpus)


def part_iteration(repeat):
    from freqid_casadi._threads import single_threaded_blas
    from freqid_casadi.core.objective import stage_functions
    from freqid_casadi.solvers.ipopt import solve_least_squares
    from freqid_casadi.solvers.termination import Termination

    rows = []
    for m in ITER_POINTS:
        data, param, z0 = _stage(m, ITER_SECTIONS)
        lb, ub = param.bounds()
        with single_threaded_blas():
            funcs = stage_functions(param, data.omega, data.response)
            lo, hi = (5, 25) if m > 10_000 else (10, 60)
            # the termination test off: both solves run to their limits
            term = Termination(ftol=0.0, noise_factor=0.0, polish_steps=0)

            def solve(k):
                return solve_least_squares(funcs, z0, lb, ub, max_iter=k, termination=term)

            solve(3)
            (r_lo, r_hi), per_it = _paired(solve, lo, hi, repeat if m > 10_000
                                           else max(repeat, ITER_REPEAT))
            floor = _floor(funcs, param, data, r_hi.x, repeat)
        it = {"wall": per_it[0], "cpu": per_it[1], "repeats": len(per_it[2]),
              "cpu_each": per_it[2],
              "build": float(r_hi.extra.get("t_build", np.nan)),
              "callbacks": {k: float(r_hi.extra.get(f"t_{k}", 0.0)) / max(r_hi.nit, 1)
                            for k in ("f", "grad_f", "hess_l")}}
        ipopt_alone = _ipopt_alone(int(param.n_vars), repeat)
        rows.append({"n_points": m, "n_sections": ITER_SECTIONS, "n_vars": int(param.n_vars),
                     "iteration": it, "floor": floor, "ratio_cpu": it["cpu"] / floor["floor"],
                     "ipopt_alone": ipopt_alone, "nit": [int(r_lo.nit), int(r_hi.nit)]})
        print(f"  iteration: {m} points: {it['cpu'] * 1e3:.2f} ms CPU against a floor of "
              f"{floor['floor'] * 1e3:.2f} ms", file=sys.stderr)
    return rows


# ----------------------------------------------------------------------------- layers

#: (layer, function of the package whose presence on the stack names it), outermost first:
#: a solve is charged to the first layer found on its stack.
LAYERS = (
    ("resolution guard's floored refit", "guard_resolution"),
    ("delay hold's refits", "hold_undetermined_delay"),
    ("zeros='free' alternative", "_with_alternatives"),
    ("h = 0 candidates", "zero_delay_run"),
    ("rescues (delay search, far roots)", ("delay_search_run", "far_root_run")),
    ("sequential loop", "sequential"),
    ("rational start's polish", "rational"),
    ("minimax", "minimax"),
)
LAYER_FITS = (("actuator", 2), ("robot arm", 3), ("resonator_36mm_s21", 2), ("tx190_s21", 3))


def _layer_of(names):
    for label, fn in LAYERS:
        if any(f in names for f in ((fn,) if isinstance(fn, str) else fn)):
            return label
    return "other"


def _layered_fit(data, n):
    """One default fit with every IPOPT solve charged to its layer."""
    import traceback

    from freqid_casadi.solvers import ipopt

    solves = []
    run = ipopt.run_nlpsol

    def counted(*args, **kw):
        names = {f.name for f in traceback.extract_stack()}
        t0, c0 = time.perf_counter(), time.process_time()
        out = run(*args, **kw)
        solves.append((_layer_of(names), int(out[0].nit), time.perf_counter() - t0,
                       time.process_time() - c0))
        return out

    ipopt.run_nlpsol = counted
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        res = fc.fit(data, n_sections=n)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        ipopt.run_nlpsol = run
    layers = {}
    for label, nit, w, c in solves:
        row = layers.setdefault(label, {"solves": 0, "nit": 0, "wall": 0.0, "cpu": 0.0})
        row["solves"] += 1
        row["nit"] += nit
        row["wall"] += w
        row["cpu"] += c
    return {"wall": wall, "cpu": cpu, "status": str(res.status.value), "start": res.start,
            "integrator_fits": len(res.details.get("integrator", {}).get("contenders", (0,))),
            "solves": len(solves),
            "nit": sum(r["nit"] for r in layers.values()),
            "solve_cpu": sum(r["cpu"] for r in layers.values()), "layers": layers}


def part_layers(repeat):
    sets = measured_sets()
    rows = []
    for name, n in LAYER_FITS:
        row = _layered_fit(sets[name], n)
        rows.append({"data": name, "n_points": int(sets[name].n_points), "n_sections": n,
                     **row})
        print(f"  layers: {name} {n}: {row['wall']:.2f} s, {row['solves']} solves, "
              f"{row['nit']} iterations", file=sys.stderr)
    return rows


# ----------------------------------------------------------------------------- fixed costs

#: (label, function names of the profile whose cumulative time is the cost).
FIXED = (
    ("stage functions (objective, derivatives)", ("stage_functions",)),
    ("nlpsol construction", ("nlpsol",)),
    ("rational start (vector fitting)", ("rational_start",)),
    ("candidates (choose, zero delay, delay search)", ("choose", "zero_delay_run",
                                                      "delay_search")),
    ("diagnostics and resolution check", ("after_fit", "_resolution_check")),
    ("covariance", ("parameter_uncertainty",)),
    ("IPOPT solve (nlpsol call)", ("Function_call",)),
)


def _profile_fit(data, **kw):
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    res = fc.fit(data, **kw)
    _ = res.uncertainty                  # the covariance, as a report asks for it
    prof.disable()
    total = time.perf_counter() - t0
    stats = pstats.Stats(prof).stats
    out = {}
    for label, names in FIXED:
        cum = [v[3] for (_f, _l, fn), v in stats.items()
               if fn in names or any(fn.endswith(f".{n}>") for n in names)]
        out[label] = float(max(cum)) if cum else 0.0
    return {"total": total, "costs": out}


def part_fixed(repeat):
    from freqid_casadi.systems.examples import EXAMPLES

    sets = measured_sets()
    a = EXAMPLES["A"]
    cases = [("actuator, 2 sections, default", sets["actuator"], dict(n_sections=2)),
             ("actuator, 2 sections, rational", sets["actuator"],
              dict(n_sections=2, start="rational")),
             ("A, 17 sections, rational", a.data(), dict(a.structure(), start="rational"))]
    rows = []
    for label, data, kw in cases:
        fc.fit(data, **kw)                                            # warm-up
        runs = [_profile_fit(data, **kw) for _ in range(max(1, repeat - 1))]
        rows.append({"fit": label, "total": _median([r["total"] for r in runs]),
                     "costs": {k: _median([r["costs"][k] for r in runs])
                               for k in runs[0]["costs"]}})
    return rows


# ----------------------------------------------------------------------------- subprocesses

_LARGE = r"""
import json, resource, sys, time, tracemalloc, warnings
import numpy as np
import freqid_casadi as fc
warnings.simplefilter("ignore")
m, n = int(sys.argv[1]), int(sys.argv[2])
data = fc.systems.G_A(np.logspace(-2, 3, m))
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
t0, c0 = time.perf_counter(), time.process_time()
res = fc.fit(data, n_sections=n, integrator=True)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
# the arrays' own peak, from a second fit under tracemalloc (which slows every allocation:
# the first fit, timed, runs without it)
tracemalloc.start()
fc.fit(data, n_sections=n, integrator=True)
peak = tracemalloc.get_traced_memory()[1] / 2**20
tracemalloc.stop()
# the default fit (integrator="auto": its contenders settled on a subset of the points)
t0, c0 = time.perf_counter(), time.process_time()
auto = fc.fit(data, n_sections=n)
rec = auto.details.get("integrator", {})
print(json.dumps({"wall": wall, "cpu": cpu, "maxrss_mib": rss, "base_rss_mib": base,
    "tracemalloc_mib": peak, "max_rel_error": float(res.max_rel_error),
    "nit": int(res.nit), "auto": {"wall": time.perf_counter() - t0,
    "cpu": time.process_time() - c0, "max_rel_error": float(auto.max_rel_error),
    "chosen": rec.get("chosen"), "contenders": rec.get("contenders"),
    "settled_on": rec.get("settled_on")}}))
"""

_SURVEY = r"""
import json, sys, time, warnings
sys.path.insert(0, sys.argv[1])
warnings.simplefilter("ignore")
from modal_benchmark import beam_channels, zeros_of
from freqid_casadi.modal.survey import stabilization
datas = beam_channels(16)
t0, c0 = time.perf_counter(), time.process_time()
res = stabilization(datas, range(2, 41, 2), delay=False, zeros=zeros_of(16))
print(json.dumps({"wall": time.perf_counter() - t0, "cpu": time.process_time() - c0,
                  "n_modes": len(res.modes)}))
"""


def _run_code(code, args, timeout):
    t0 = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, "-c", code, *map(str, args)], text=True,
                             capture_output=True, timeout=timeout,
                             env=dict(os.environ, PYTHONPATH=ROOT))
    except subprocess.TimeoutExpired:
        return {"error": f"not finished within {timeout} s"}
    if out.returncode:
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1]}
    row = json.loads(out.stdout.strip().splitlines()[-1])
    row["subprocess_wall"] = time.perf_counter() - t0
    return row


def part_large(repeat, timeout):
    return {"n_points": LARGE_POINTS, "n_sections": LARGE_SECTIONS,
            **_run_code(_LARGE, [LARGE_POINTS, LARGE_SECTIONS], timeout)}


def part_sweep(repeat):
    from freqid_casadi.fitting.sweep import parse_orders, sweep

    data = fc.systems.G_A()
    orders = parse_orders("2:40:2")
    res, wall, cpu = _timed(lambda: sweep(data, orders, integrator=True), max(1, repeat - 1))
    return {"orders": "2:40:2", "wall": wall, "cpu": cpu,
            "max_rel_errors": [float(r.max_rel_error) for r in res.rows]}


def part_survey(repeat, timeout):
    return {"channels": 16, "n_points": 1000, "orders": "2:40:2",
            **_run_code(_SURVEY, [os.path.join(ROOT, "scripts")], timeout)}


def _batch_data(n):
    sys.path.insert(0, os.path.join(ROOT, "scripts"))
    from batch_benchmark import make_datasets

    folder = tempfile.mkdtemp(prefix="speed-batch-")
    make_datasets(folder, n)
    return sorted(os.path.join(folder, f) for f in os.listdir(folder) if f.endswith(".csv"))


def part_batch(repeat):
    paths = _batch_data(N_BATCH)
    try:
        return _batch_runs(paths, repeat)
    finally:
        import shutil

        shutil.rmtree(os.path.dirname(paths[0]), ignore_errors=True)


def _speedups(runs):
    """Median of each pair's speed-up (1 over 2), the pairs' speed-ups, and the median
    times (a pair runs back to back, so that a slow spell of the shared machine falls on
    both of its runs)."""
    ratios = [r[1] / r[2] for r in runs]
    return {1: _median([r[1] for r in runs]), 2: _median([r[2] for r in runs]),
            "speedup": _median(ratios), "speedups": ratios}


def _batch_runs(paths, repeat):
    from freqid_casadi.fitting.batch import fit_many

    opts = dict(n_sections=4, integrator=True)
    out = {"n": len(paths), "repeat": repeat, "ok": {}}
    runs = []
    for _ in range(repeat):
        runs.append({})
        for jobs in (1, 2):
            t0 = time.perf_counter()
            items = fit_many(paths, n_jobs=jobs, **opts)
            runs[-1][jobs] = time.perf_counter() - t0
            out["ok"][f"local{jobs}"] = sum(1 for it in items if it.ok)
    out["local"] = _speedups(runs)
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        out["dask"] = {"error": "dask not installed"}
        return out
    runs, cpus = [], {}
    for _ in range(repeat):
        runs.append({})
        for workers in (1, 2):
            runs[-1][workers], cpus[workers], out["ok"][f"dask{workers}"] = _dask_batch(
                Client, LocalCluster, workers, paths, opts)
    out["dask"] = _speedups(runs)
    out["dask"].update({f"cpu{w}": c for w, c in cpus.items()})
    return out


def _dask_batch(client_cls, cluster_cls, workers, paths, opts):
    """(wall seconds, CPU seconds {here, workers}, fits ok) of one batch on a fresh local
    cluster of ``workers`` single-threaded worker processes."""
    from freqid_casadi.fitting.batch import fit_many

    with cluster_cls(n_workers=workers, threads_per_worker=1, processes=True,
                     dashboard_address=None) as cluster, client_cls(cluster) as client:
        # the workers up and the package imported before the clock starts, as a forked
        # local worker starts with it (a spawned worker's first task would import it,
        # about 0.8 s on every worker at once: the cluster's start-up, not the batch)
        client.run(importlib.import_module, "freqid_casadi.fitting.batch")
        w0, c0, t0 = client.run(time.process_time), time.process_time(), time.perf_counter()
        items = fit_many(paths, scheduler=client, **opts)
        wall = time.perf_counter() - t0
        w1 = client.run(time.process_time)
        # CPU seconds of this process (the client and the cluster's scheduler) and of each
        # worker during the batch: what the workers did not get of the cores
        cpu = {"here": time.process_time() - c0, "workers": sorted(w1[k] - w0[k] for k in w0)}
    return wall, cpu, sum(1 for it in items if it.ok)


# ----------------------------------------------------------------------------- report


def _fits_md(rows):
    lines = ["## Fits on the measured sets beside scikit-rf's vector fitting", "",
             f"Median of the repeats (vector fitting, a few ms a call: of {VF_REPEAT}); "
             "`ratio` is the package's time over vector fitting's (CPU seconds of this "
             "process; wall in parentheses).", "",
             "| data | points | order | start | time (s) | CPU (s) | iterations | max rel. "
             "error | VF time (ms) | VF max rel. error | ratio CPU (wall) |",
             "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['data']} | {r['n_points']} | {r['order']} | {r['start']} | "
                     f"{r['wall']:.3f} | {r['cpu']:.3f} | {r['nit']} | "
                     f"{r['max_rel_error']:.4g} | {r['vf']['wall'] * 1e3:.1f} | "
                     f"{r['vf']['max_rel_error']:.4g} | {r['ratio_cpu']:.0f} "
                     f"({r['ratio_wall']:.0f}) |")
    for variant in VARIANTS:
        label = _label(*variant)
        rr = [r["ratio_cpu"] for r in rows if r["start"] == label]
        rw = [r["ratio_wall"] for r in rows if r["start"] == label]
        if rr:
            lines.append(f"\nMedian ratio, start={label!r}: **{_median(rr):.0f}** CPU, "
                         f"{_median(rw):.0f} wall (targets: default <= 10, rational <= 3).")
    lines.append("\n`k and sign given`: the fit with `integrator` and `gain_sign` set to "
                 "the default fit's choices (what a user who knows them passes; the same "
                 "model where the choice is the default's): the time the automatic "
                 "choices take is the difference.")
    return lines


def _iteration_md(rows):
    lines = ["## One IPOPT iteration against its floor", "",
             "A 5-section stage of example A's system (22 variables). Whole iteration: CPU "
             "seconds per IPOPT iteration of the package (median over pairs of capped solves run "
             "back to back, of each pair's difference of times over its difference of "
             "iterations; the quartiles of the pairs in parentheses). "
             "Floor: one residual, one Jacobian (its pieces recomputed), one exact Hessian "
             "and one dense solve of that size, timed in numpy in the same run (`J^T J` alone "
             "for comparison).", "",
             "| points | iteration (ms CPU) | wall (ms) | residual | Jacobian | J^T J | exact "
             "Hessian | solve | floor (ms) | ratio | per-iteration callbacks f / grad / "
             "Hessian (ms wall) | NLP build (s) | IPOPT alone (ms) | least ratio with IPOPT |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|"]
    for r in rows:
        f, it = r["floor"], r["iteration"]
        cb = " / ".join(f"{it['callbacks'][k] * 1e3:.2f}" for k in ("f", "grad_f", "hess_l"))
        each = it.get("cpu_each") or [it["cpu"]]
        q1, q3 = (np.percentile(each, q) * 1e3 for q in (25, 75))
        lines.append(f"| {r['n_points']} | {it['cpu'] * 1e3:.2f} ({q1:.2f}-{q3:.2f}, "
                     f"{len(each)} pairs) | {it['wall'] * 1e3:.2f} | "
                     + " | ".join(f"{f[k] * 1e3:.3f}" for k in ("residual", "jacobian", "jtj",
                                                                 "hessian", "solve"))
                     + f" | {f['floor'] * 1e3:.2f} | **{r['ratio_cpu']:.2f}** | {cb} | "
                     f"{it['build']:.3f} | {r.get('ipopt_alone', float('nan')) * 1e3:.3f} | "
                     f"{_least_ratio(r):.2f} |")
    lines.append("\nTarget: ratio <= 2 at 500 and at 50 000 points. `IPOPT alone`: IPOPT's "
                 "own CPU per iteration on a dense bounded NLP of the same number of "
                 "variables whose functions are CasADi SX (no Python), with the package's "
                 "options for an NLP of bounds only, the part of the "
                 "iteration no change of the package's evaluations removes. `least ratio with "
                 "IPOPT`: (floor + IPOPT alone) / floor, the ratio of an iteration whose "
                 "evaluations cost exactly the floor and nothing else (no trial point of "
                 "the line search, no termination test, no call into Python): where it "
                 "nears 2, the target is out of reach of any change of the package's "
                 "evaluations while IPOPT solves the stage.")
    return lines


def _least_ratio(row):
    """(floor + IPOPT's own CPU per iteration) / floor: the smallest ratio an iteration
    solved by IPOPT can have."""
    f = row["floor"]["floor"]
    return (f + row.get("ipopt_alone", float("nan"))) / f


def _layers_md(rows):
    labels = [label for label, _ in LAYERS] + ["other"]
    lines = ["## Where a default fit's time goes", "",
             "One default fit (`fc.fit(data, n_sections=N)`) per row; each IPOPT solve is "
             "charged to the layer of the pipeline that ran it (`solves / iterations / CPU "
             "s`); `integrator fits`: the fits the automatic integrator ran (its contenders, "
             "when the rational starts do not decide); `outside IPOPT`: CPU seconds of the rest "
             "(vector fittings, "
             "diagnostics, covariance, bookkeeping).", "",
             "| data | points | N | status | wall (s) | CPU (s) | integrator fits | solves | "
             "iterations | " + " | ".join(labels) + " | outside IPOPT (s) |",
             "|---|---:|---:|---|---:|---:|---:|---:|---:|" + "---|" * len(labels) + "---:|"]
    for r in rows:
        cells = []
        for label in labels:
            c = r["layers"].get(label)
            cells.append(f"{c['solves']} / {c['nit']} / {c['cpu']:.2f}" if c else "—")
        lines.append(f"| {r['data']} | {r['n_points']} | {r['n_sections']} | {r['status']} | "
                     f"{r['wall']:.2f} | {r['cpu']:.2f} | {r['integrator_fits']} | "
                     f"{r['solves']} | {r['nit']} | " + " | ".join(cells)
                     + f" | {r['cpu'] - r['solve_cpu']:.2f} |")
    return lines


def _fixed_md(rows):
    labels = [label for label, _ in FIXED]
    lines = ["## Fixed costs per fit", "",
             "Cumulative seconds under cProfile (the profiler inflates Python-heavy parts; "
             "read the shares), median of the repeats.", "",
             "| fit | total (s) | " + " | ".join(labels) + " |",
             "|---|---:|" + "---:|" * len(labels)]
    for r in rows:
        lines.append(f"| {r['fit']} | {r['total']:.3f} | "
                     + " | ".join(f"{r['costs'][k]:.3f}" for k in labels) + " |")
    return lines


def _one_md(title, row, keys):
    if "error" in row:
        return [f"## {title}", "", f"{row['error']}."]
    return [f"## {title}", "", ", ".join(f"{k}: {row[k]:.4g}" if isinstance(row[k], float)
                                         else f"{k}: {row[k]}" for k in keys if k in row)
            + "."]


def _auto_large_md(a):
    """The default fit's line of the 200 000-point part (``integrator="auto"``)."""
    if not a:
        return []
    on = a.get("settled_on")
    how = (f"settled on {on['points']} of the {on['of']} points" if on else
           "fitted on all points")
    return [f"The default fit (`integrator='auto'`): {a['wall']:.2f} s wall, "
            f"{a['cpu']:.2f} s CPU, max rel. error {a['max_rel_error']:.4g}; contenders "
            f"{a['contenders']} ({how}), k = {a['chosen']} kept.", ""]


def _batch_md(b):
    pairs = b.get("repeat", 1)
    lines = [f"## Batch of {b['n']} FRFs, 2 jobs against 1", "",
             f"{pairs} pairs of batches (1 job, then 2 jobs, back to back); the median of "
             "the pairs' speed-ups, each pair's in parentheses, and the median times.", ""]

    def each(d):
        return ", ".join(f"{x:.2f}" for x in d.get("speedups", [d["speedup"]]))

    loc = b["local"]
    lines.append(f"Local processes: 1 job {loc[1]:.1f} s, 2 jobs {loc[2]:.1f} s, speed-up "
                 f"**{loc['speedup']:.2f}** ({each(loc)}; target >= 1.8).")
    d = b.get("dask", {})
    if "error" in d:
        lines.append(f"Dask: {d['error']}.")
    elif d:
        lines.append(f"Local Dask cluster: 1 worker {d[1]:.1f} s, 2 workers {d[2]:.1f} s, "
                     f"speed-up **{d['speedup']:.2f}** ({each(d)}; target >= 1.8; the "
                     "workers started and the package imported in them before the clock, as "
                     "a forked local worker starts with it).")
        cpu = d.get("cpu2")
        if cpu:
            share = cpu["here"] / d[2]
            lines.append(
                f"During the last 2-worker batch this process (the client and the cluster's "
                f"scheduler) used {cpu['here']:.2f} CPU s, the workers "
                f"{' and '.join(f'{w:.2f}' for w in cpu['workers'])}: with the scheduler on "
                f"the same {os.cpu_count()} cores, the workers have at most "
                f"{os.cpu_count() - share:.2f} of them (the nannies' housekeeping not "
                "counted).")
    lines.append(f"Fits that succeeded: {b.get('ok')}.")
    return lines


def markdown(command, out):
    lines = [f"<!-- generated by: {command} -->", "", "# Speed (issue 30)", "",
             f"Machine: {os.cpu_count()} CPUs shared with other engineers (load average "
             f"{', '.join(f'{x:.1f}' for x in out['load'])} over the run), Python "
             f"{platform.python_version()}. Absolute times are noisy; single-process "
             f"numbers are medians of {out['repeat']} repeats, with CPU seconds beside the "
             "wall time, and the conclusions are ratios measured in this run. Every number is "
             "in `speed.json`.", "",
             *computed_on_lines(out.get("environment"))]
    if "fits" in out:
        lines += _fits_md(out["fits"]) + [""]
    if "iteration" in out:
        lines += _iteration_md(out["iteration"]) + [""]
    if "layers" in out:
        lines += _layers_md(out["layers"]) + [""]
    if "fixed" in out:
        lines += _fixed_md(out["fixed"]) + [""]
    if "large" in out:
        lines += _one_md("200 000 points, 2 sections (one fit, fresh subprocess)", out["large"],
                         ["wall", "cpu", "maxrss_mib", "base_rss_mib", "tracemalloc_mib",
                          "max_rel_error", "nit"])
        lines += ["", "Targets: <= 10 s and <= 300 MiB peak (the fit with example A's "
                  "integrator, `integrator=True`).", ""]
        lines += _auto_large_md(out["large"].get("auto"))
    if "sweep" in out:
        s = out["sweep"]
        lines += [f"## Sweep of example A over orders {s['orders']}", "",
                  f"{s['wall']:.2f} s wall, {s['cpu']:.2f} s CPU (target <= 2 s).", ""]
    if "survey" in out:
        lines += _one_md("Stabilization survey, 16 channels x 1000 points, orders 2:40:2",
                         out["survey"], ["wall", "cpu", "n_modes"])
        lines += ["", "Target: <= 10 s.", ""]
    if "batch" in out:
        lines += _batch_md(out["batch"]) + [""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--timeout", type=float, default=240.0,
                    help="seconds allowed to each subprocess part (large, survey)")
    args = ap.parse_args(argv)
    parts = [p for p in args.parts.split(",") if p]
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        ap.error(f"unknown part(s) {unknown}; choose from {', '.join(PARTS)}")
    warnings.simplefilter("ignore")
    # one BLAS thread for the whole run, as every fit of the package runs: vector fitting and
    # the numpy floor then do the same single-threaded work, and no idle OpenBLAS thread
    # spins beside a timed call (it charged vector fitting up to twice its wall time in CPU)
    from freqid_casadi._threads import single_threaded_blas

    blas = single_threaded_blas()  # noqa: F841 (held for the run)
    command = "python scripts/speed.py" + "".join(
        f" --{k} {v}" for k, v in (("out", args.out), ("repeat", args.repeat),
                                   ("parts", args.parts)) if v != ap.get_default(k))
    out = {"command": command, "repeat": args.repeat, "load": [os.getloadavg()[0]],
           "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
           "environment": environment()}
    runners = {"fits": part_fits, "iteration": part_iteration, "layers": part_layers,
               "fixed": part_fixed,
               "large": lambda r: part_large(r, args.timeout), "sweep": part_sweep,
               "survey": lambda r: part_survey(r, args.timeout), "batch": part_batch}
    for p in PARTS:
        if p in parts:
            t0 = time.perf_counter()
            out[p] = runners[p](args.repeat)
            out.setdefault("part_wall", {})[p] = time.perf_counter() - t0
            out["load"].append(os.getloadavg()[0])
            print(f"{p}: {out['part_wall'][p]:.1f} s", file=sys.stderr)
    out["maxrss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    text = markdown(command, out)
    os.makedirs(args.out, exist_ok=True)
    atomic_write_text(os.path.join(args.out, "speed.md"), text)
    atomic_write_text(os.path.join(args.out, "speed.json"),
                      json.dumps(out, indent=1, default=str) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

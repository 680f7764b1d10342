"""Spread of the headline fits over OpenBLAS kernels, numpy's SIMD paths and rounding-level
data perturbations.

Usage::

    python scripts/reproducibility.py [--quick] [--jobs 2] [--out results] [--seeds 10] [--keep DIR]

Runs the headline fits (examples A, B and C with ``start="sequential"`` and
``start="rational"``, B with ``objective="minimax"``, the actuator at 1-3 sections
(:func:`freqid_casadi.studies.measured.actuator_frf`), the DaISy robot arm with a delay at
1-5 sections (:func:`freqid_casadi.studies.robot_arm.arm_data`), the shared-pole modal
benchmark of ``scripts/modal_benchmark.py`` (16 channels, 10 modes) and the sweep of A over
orders 2:20:2 (``scripts/sweep_benchmark.py``; 2:40:2 took 10 min a run on the shared
machine)) in worker subprocesses, at most ``--jobs`` (<= 2) at a time:

* once per OpenBLAS kernel (``OPENBLAS_CORETYPE`` = Haswell, SkylakeX, Zen, Sandybridge,
  Nehalem, Prescott), set in the worker's environment only; the worker records with
  threadpoolctl which kernel OpenBLAS actually loaded;
* once per seed 0..9 with the machine's own kernel and every data point multiplied by
  ``1 + 1e-15 (a + i b) / sqrt(2)``, a and b standard normal (a relative perturbation at
  the rounding level);
* once as the machine runs it, and once per level of numpy's SIMD dispatch this CPU has
  (X86_V3 = AVX2, X86_V4 = AVX-512, ...): that level and those above it switched off with
  ``NPY_DISABLE_CPU_FEATURES`` in the worker's environment, so the run takes the functions
  (``exp``, ``sin``, ``cos``, complex arithmetic) of the next level down, as a CPU without
  it would. The worker records which level numpy dispatched.

Writes ``reproducibility.md`` (first line: this command) and ``reproducibility.json`` to
``--out``: per fit, min / median / max of the max relative error, the delay and the IPOPT
iterations, and the statuses, over the kernels, over the perturbations, over numpy's
SIMD levels, and over all. ``--quick`` (development): examples A and B only, two kernels,
two seeds (and every SIMD level).
"""

import argparse
import json
import os
import signal
import subprocess
import sys
import time
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KERNELS = ("Haswell", "SkylakeX", "Zen", "Sandybridge", "Nehalem", "Prescott")
SEEDS = tuple(range(10))
PERTURBATION = 1e-15


def numpy_levels():
    """numpy's SIMD dispatch levels this CPU has, lowest first (e.g. ``["X86_V3"]``).

    Empty where numpy does not say (a build without runtime dispatch, a numpy that moved
    the table): the study then has no numpy axis.
    """
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:
        return []
    return [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]


def _numpy_dispatch():
    """The target numpy dispatched for a few of the fits' hot functions (float64/complex128)."""
    try:
        from numpy.lib.introspect import opt_func_info
    except ImportError:          # numpy < 2.0
        return {}
    info = opt_func_info(func_name="^(exp|sin|cos|multiply)$", signature="float64|complex128")
    return {f"{name} {sig}": t["current"] for name, d in sorted(info.items())
            for sig, t in d.items() if sig in ("dd", "DDD")}


def _perturbed(data, seed):
    """``data`` with its response times 1 + 1e-15 (a + ib)/sqrt(2) (seed None: unchanged)."""
    import dataclasses

    if seed is None:
        return data
    rng = np.random.default_rng([27, seed, data.response.size])
    z = (rng.normal(size=data.response.size)
         + 1j * rng.normal(size=data.response.size)) / np.sqrt(2)
    return dataclasses.replace(data, response=data.response * (1 + PERTURBATION * z))


def _row(res):
    last = res.stages[-1]
    return {"max_rel_error": float(res.max_rel_error), "delay": float(res.model.delay),
            "nit": int(res.nit),
            "status": str(getattr(res.status, "value", res.status)),
            "final_stage_solver_status": last.solver_status,
            "wall_time": float(res.wall_time)}


def _examples(seed, quick):
    import freqid_casadi as fc
    from freqid_casadi.systems.examples import EXAMPLES

    out = {}
    for name in ("A", "B") if quick else ("A", "B", "C"):
        ex = EXAMPLES[name]
        data = _perturbed(ex.data(), seed)
        for start in ("sequential", "rational"):
            out[f"{name} {start}"] = lambda d=data, e=ex, s=start: _row(
                fc.fit(d, **e.structure(), start=s))
        if name == "B":
            out["B minimax"] = lambda d=data, e=ex: _row(
                fc.fit(d, **e.structure(), objective="minimax"))
    return out


def _measured(seed, quick):
    import freqid_casadi as fc
    from freqid_casadi.studies.measured import actuator_frf, fit_row
    from freqid_casadi.studies.robot_arm import arm_data

    out = {}
    act = _perturbed(actuator_frf().data, seed)
    for n in (1,) if quick else (1, 2, 3):
        out[f"actuator {n} section{'s' if n > 1 else ''}"] = (
            lambda n=n: _row(fit_row(act, n)[1]))
    arm = _perturbed(arm_data()[1], seed)
    for n in (2,) if quick else (1, 2, 3, 4, 5):
        out[f"robot arm {n} sections, delay"] = lambda n=n: _row(
            fc.fit(arm, n_sections=n, integrator=False, delay=True))
    return out


def _modal(seed, quick):
    sys.path.insert(0, os.path.join(ROOT, "scripts"))
    import modal_benchmark as mb
    from freqid_casadi.modal.shared import fit_shared

    channels = 8 if quick else 16

    def run():
        datas = [_perturbed(d, seed) for d in mb.beam_channels(channels)]
        t0 = time.perf_counter()
        res = fit_shared(datas, mb.N_MODES, delay=False, zeros=mb.zeros_of(channels))
        return {"max_rel_error": float(np.max(res.max_rel_errors)), "delay": 0.0,
                "nit": int(res.nit), "wall_time": time.perf_counter() - t0,
                "status": f"{getattr(res.status, 'value', res.status)}, "
                          f"{len(res.modes)} modes",
                "final_stage_solver_status": res.stages[-1].solver_status}

    return {f"modal beam {channels} channels x 10 modes": run}


def _sweep(seed, quick):
    import freqid_casadi as fc
    from freqid_casadi.fitting.sweep import parse_orders, sweep

    orders = "2:10:2" if quick else "2:20:2"      # 2:40:2 took 10 min a run here

    def run():
        t0 = time.perf_counter()
        res = sweep(_perturbed(fc.systems.G_A(), seed), parse_orders(orders), integrator=True)
        errs = [r.max_rel_error for r in res.rows]
        last = res.rows[-1]
        mono = all(b <= a for a, b in zip(errs, errs[1:]))
        return {"max_rel_error": float(last.max_rel_error), "delay": float(last.delay),
                "nit": None, "wall_time": time.perf_counter() - t0,
                "status": f"{sum(r.success for r in res.rows)}/{len(res.rows)} converged, "
                          f"{'non-increasing' if mono else 'NOT non-increasing'}"}

    return {f"sweep A {orders}, last order": run}


def worker(seed, quick, path):
    """Run every fit in this process and write its rows (JSON) to ``path``."""
    import threadpoolctl

    import freqid_casadi as fc

    warnings.simplefilter("ignore")
    info = [{"prefix": i.get("prefix"), "architecture": i.get("architecture"),
             "version": i.get("version")}
            for i in threadpoolctl.threadpool_info() if i.get("internal_api") == "openblas"]
    where = os.environ.get("OPENBLAS_CORETYPE") or (
        f"numpy without {os.environ['NPY_DISABLE_CPU_FEATURES']}"
        if os.environ.get("NPY_DISABLE_CPU_FEATURES") else "default")
    fits = {}
    for group in (_examples, _measured, _modal, _sweep):
        fits.update(group(seed, quick))
    rows = {}
    for name, run in fits.items():
        try:
            rows[name] = run()
        except fc.errors.FreqidError as exc:      # recorded, not fatal: a row says why
            rows[name] = {"max_rel_error": None, "delay": None, "nit": None,
                          "status": f"error: {type(exc).__name__}: {exc}"}
        print(f"  [{where}, seed {seed}] {name}: "
              f"{rows[name]['max_rel_error']}", file=sys.stderr, flush=True)
    with open(path, "w", encoding="utf-8") as fh:
        json.dump({"openblas": info, "numpy_dispatch": _numpy_dispatch(), "rows": rows},
                  fh, indent=1)


def _configs(quick, n_seeds=len(SEEDS), levels=()):
    """The workers to run: kernels, seeds, then numpy's SIMD levels (``numpy``: the
    features to switch off, "" for the machine as it is, None outside that axis)."""
    kernels = KERNELS[:2] if quick else KERNELS
    seeds = SEEDS[:2] if quick else SEEDS[:n_seeds]
    simd = [" ".join(levels[i:]) for i in range(len(levels) - 1, -1, -1)]
    return ([{"kernel": k, "seed": None, "numpy": None} for k in kernels]
            + [{"kernel": None, "seed": s, "numpy": None} for s in seeds]
            + [{"kernel": None, "seed": None, "numpy": n} for n in ([""] + simd if simd else [])])


def _run_all(configs, quick, jobs, tmp):
    """Start the workers, at most ``jobs`` at a time; return their results in order."""
    pending, running, done = [], [], {}
    for i, c in enumerate(configs):      # a worker's output from an earlier run is reused
        path = os.path.join(tmp, f"worker{i}.json")
        if os.path.exists(path):
            with open(path, encoding="utf-8") as fh:
                done[i] = dict(c, **json.load(fh))
            print(f"reused {_label(c)} ({path})", flush=True)
        else:
            pending.append((i, c))
    t0 = time.perf_counter()
    while pending or running:
        while pending and len(running) < jobs:
            i, c = pending.pop(0)
            env = dict(os.environ)
            env.pop("OPENBLAS_CORETYPE", None)
            env.pop("NPY_DISABLE_CPU_FEATURES", None)
            if c["kernel"]:
                env["OPENBLAS_CORETYPE"] = c["kernel"]
            if c.get("numpy"):
                env["NPY_DISABLE_CPU_FEATURES"] = c["numpy"]
            env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
            path = os.path.join(tmp, f"worker{i}.json")
            cmd = [sys.executable, os.path.abspath(__file__), "--worker", "--json", path]
            cmd += ["--seed", str(c["seed"])] if c["seed"] is not None else []
            cmd += ["--quick"] if quick else []
            log = open(os.path.join(tmp, f"worker{i}.log"), "w", encoding="utf-8")
            running.append((i, c, path, log, subprocess.Popen(cmd, env=env, cwd=ROOT,
                                                              stderr=log, stdout=log)))
            print(f"[{time.perf_counter() - t0:6.0f} s] start {_label(c)}", flush=True)
        time.sleep(1.0)
        for item in list(running):
            i, c, path, log, proc = item
            if proc.poll() is None:
                continue
            running.remove(item)
            log.close()
            if proc.returncode == -signal.SIGILL:       # a kernel this CPU cannot run
                done[i] = dict(c, skipped="illegal instruction: this CPU lacks the "
                               "instructions of that kernel", openblas=[], rows={})
                print(f"[{time.perf_counter() - t0:6.0f} s] skip  {_label(c)}: illegal "
                      "instruction on this CPU", flush=True)
                continue
            if proc.returncode != 0:
                with open(log.name, encoding="utf-8") as fh:
                    raise SystemExit(f"worker {_label(c)} failed:\n{fh.read()[-3000:]}")
            with open(path, encoding="utf-8") as fh:
                done[i] = dict(c, **json.load(fh))
            print(f"[{time.perf_counter() - t0:6.0f} s] done  {_label(c)} "
                  f"({len(done)}/{len(configs)})", flush=True)
    return [done[i] for i in range(len(configs))]


def _label(c):
    if c["kernel"]:
        return f"OPENBLAS_CORETYPE={c['kernel']}"
    if c["seed"] is not None:
        return f"default kernel, perturbation seed {c['seed']}"
    return (f"NPY_DISABLE_CPU_FEATURES={c['numpy']!r}" if c.get("numpy")
            else "the machine as it is")


def _stats(values):
    v = [x for x in values if x is not None]
    if not v:
        return None
    return {"min": float(np.min(v)), "median": float(np.median(v)), "max": float(np.max(v))}


def summarise(runs):
    """Per fit and per group ('kernels', 'perturbations', 'all'): min/median/max and statuses."""
    runs = [r for r in runs if not r.get("skipped")]
    names = list(runs[0]["rows"])
    groups = {"kernels": [r for r in runs if r["kernel"]],
              "perturbations": [r for r in runs if r["seed"] is not None],
              "numpy": [r for r in runs if r.get("numpy") is not None], "all": runs}
    groups = {g: rs for g, rs in groups.items() if rs}
    out = {}
    for name in names:
        out[name] = {}
        for g, rs in groups.items():
            rows = [r["rows"][name] for r in rs]
            statuses = {}
            for x in rows:
                statuses[x["status"]] = statuses.get(x["status"], 0) + 1
            out[name][g] = {k: _stats([x[k] for x in rows])
                            for k in ("max_rel_error", "delay", "nit")}
            out[name][g]["statuses"] = statuses
            out[name][g]["n"] = len(rows)
    return out


def _fmt(s, f):
    if s is None:
        return "-"
    return " / ".join(f(s[k]) for k in ("min", "median", "max"))


def _machine():
    """One line: the CPU, numpy's SIMD levels, the versions (the package's environment())."""
    from freqid_casadi.report.environment import environment

    env, levels = environment(), numpy_levels()
    return (f"Machine: {env['cpu']}, {env['cpu_count']} CPUs; numpy {env['numpy']} with SIMD "
            f"levels {', '.join(levels) if levels else 'none beyond its baseline'}; Python "
            f"{env['python']}.")


def _numpy_table(runs):
    """Which functions numpy dispatched in each run of the SIMD axis (markdown lines)."""
    rs = [r for r in runs if r.get("numpy") is not None]
    if not rs:
        return ["numpy's SIMD levels: numpy does not report them here; not varied.", ""]
    keys = list(rs[0].get("numpy_dispatch", {}))
    lines = ["numpy's SIMD levels: `NPY_DISABLE_CPU_FEATURES` set in the worker's environment "
             "only (the level and those above it off); the target numpy dispatched, read in "
             "the worker:", "",
             "| switched off | " + " | ".join(f"`{k}`" for k in keys) + " |",
             "|---|" + "---|" * len(keys)]
    for r in rs:
        d = r.get("numpy_dispatch", {})
        lines.append(f"| {r['numpy'] or 'nothing (the machine as it is)'} | "
                     + " | ".join(str(d.get(k, "-")) for k in keys) + " |")
    return lines + [""]


def _per_level(runs, summary):
    """Each fit's max relative error and IPOPT iterations at each numpy SIMD level."""
    rs = [r for r in runs if r.get("numpy") is not None]
    if not rs:
        return []
    heads = [f"without {r['numpy']}" if r["numpy"] else "as it is" for r in rs]
    lines = ["## Per numpy SIMD level", "",
             "Max rel. error (IPOPT iterations) of each run.", "",
             "| fit | " + " | ".join(heads) + " |", "|---|" + "---:|" * len(rs)]
    for name in summary:
        cells = []
        for r in rs:
            x = r["rows"][name]
            err = x["max_rel_error"]
            cells.append("-" if err is None else f"{err:.3g}"
                         + (f" ({x['nit']})" if x.get("nit") is not None else ""))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines + [""]


def render(command, runs, summary):
    lines = [f"<!-- generated by: {command} -->", "",
             "# Reproducibility: spread over OpenBLAS kernels, numpy's SIMD paths and "
             "rounding-level perturbations", "", _machine(),
             "", "Each configuration ran in its own subprocess (at most 2 at a time). Kernels: "
             "`OPENBLAS_CORETYPE` set in that subprocess's environment only; the kernel "
             "OpenBLAS actually loaded, read by threadpoolctl in the worker:", "",
             "| requested | loaded (each OpenBLAS library in the process: numpy's, scipy's) |",
             "|---|---|"]
    for r in runs:
        if r["kernel"]:
            lines.append(f"| {r['kernel']} | " + (
                f"not run: {r['skipped']}" if r.get("skipped")
                else " / ".join(str(i["architecture"]) for i in r["openblas"])) + " |")
    base = [r for r in runs if r["seed"] is not None]
    if base:
        lines += ["", "Perturbations: the machine's own kernel ("
                  + " / ".join(str(i["architecture"]) for i in base[0]["openblas"])
                  + f"), every data point times 1 + {PERTURBATION:g} (a + i b)/sqrt(2), a, b "
                  f"standard normal, seeds {', '.join(str(r['seed']) for r in base)}.", ""]
    lines += _numpy_table(runs)
    e = lambda x: f"{x:.3g}"              # noqa: E731
    d = lambda x: f"{x:.7g}"              # noqa: E731
    i = lambda x: f"{x:.0f}"              # noqa: E731
    titles = {"kernels": "Over the OpenBLAS kernels",
              "perturbations": "Over the perturbed data (machine's kernel)",
              "numpy": "Over numpy's SIMD levels (machine's kernel)", "all": "Over all"}
    for g in next(iter(summary.values())):
        title = titles[g]
        lines += [f"## {title}", "", "min / median / max.", "",
                  "| fit | runs | max rel. error | max/min | delay | IPOPT iterations | "
                  "statuses (count) |", "|---|---:|---|---:|---|---|---|"]
        for name, s in summary.items():
            x = s[g]
            err = x["max_rel_error"]
            ratio = (f"{err['max'] / err['min']:.3g}" if err and err["min"] > 0 else "-")
            st = "; ".join(f"{k} ({v})" for k, v in x["statuses"].items())
            lines.append(f"| {name} | {x['n']} | {_fmt(err, e)} | {ratio} | "
                         f"{_fmt(x['delay'], d)} | {_fmt(x['nit'], i)} | {st} |")
        lines.append("")
    lines += _per_level(runs, summary)
    lines += ["Delays in s for the examples and the actuator, in samples for the robot arm; "
              "the modal fit has no delay; the sweep's iterations are not collected.", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="A and B only, 2 kernels, 2 seeds")
    ap.add_argument("--jobs", type=int, default=2, help="workers at a time (1 or 2)")
    ap.add_argument("--out", default=None,
                    help="folder of reproducibility.md/.json (default results; a --quick run "
                         "needs its own)")
    ap.add_argument("--seeds", type=int, default=len(SEEDS),
                    help=f"perturbation seeds 0..N-1 (default {len(SEEDS)}, at most that)")
    ap.add_argument("--keep", metavar="DIR",
                    help="keep each worker's output in DIR (worker<i>.json) and reuse those "
                         "already there: an interrupted run resumes")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--seed", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--json", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(args.seed, args.quick, args.json)
        return 0
    if not 1 <= args.jobs <= 2:
        ap.error(f"--jobs must be 1 or 2 (got {args.jobs}): the machine has 2 cores")
    if args.out is None and args.quick:
        ap.error("--quick runs A and B on 2 kernels only, which would replace the full "
                 "run's results/reproducibility.md: pass --out DIR")
    given_out, args.out = args.out, args.out or os.path.join(ROOT, "results")
    import tempfile

    from freqid_casadi.report.folder import atomic_write_text

    if not 1 <= args.seeds <= len(SEEDS):
        ap.error(f"--seeds must be 1..{len(SEEDS)} (got {args.seeds})")
    command = "python scripts/reproducibility.py" + (" --quick" if args.quick else "") + (
        f" --seeds {args.seeds}" if args.seeds != len(SEEDS) else "") + (
        f" --out {given_out}" if given_out else "")
    t0 = time.perf_counter()
    levels = numpy_levels()
    if args.keep:
        os.makedirs(args.keep, exist_ok=True)
        runs = _run_all(_configs(args.quick, args.seeds, levels), args.quick, args.jobs,
                        args.keep)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            runs = _run_all(_configs(args.quick, args.seeds, levels), args.quick, args.jobs,
                            tmp)
    summary = summarise(runs)
    os.makedirs(args.out, exist_ok=True)
    result = {"command": command, "perturbation": PERTURBATION, "runs": runs,
              "summary": summary, "wall_time": time.perf_counter() - t0}
    atomic_write_text(os.path.join(args.out, "reproducibility.json"),
                      json.dumps(result, indent=1) + "\n")
    text = render(command, runs, summary)
    atomic_write_text(os.path.join(args.out, "reproducibility.md"), text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

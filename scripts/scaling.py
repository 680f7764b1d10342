"""Scaling benchmark: time per iteration and peak memory against M and n_sections (issue 8.4).

Usage::

    python scripts/scaling.py [--out results/scaling] [--quick --out DIR]

For example A's system (G_A with integrator and delay) on a log grid of M points from 1e-2
to 1e3 rad/s, one stage NLP with ``n_sections`` sections (the stage functions of
:func:`freqid_casadi.core.objective.stage_functions`, started from the same
section placement for every M) is solved by

- IPOPT (:func:`freqid_casadi.solvers.ipopt.solve_least_squares`, exact Hessian), and
- the barrier Levenberg-Marquardt (:func:`freqid_casadi.solvers.barrier_lm.barrier_lm`,
  the residual/Jacobian of the same stage functions, as ``fit(method="barrier-lm")``).

Time per iteration is the difference quotient of two capped solves (20 vs 2 iterations,
after a warm-up solve; best of two unless the point is large; 6 vs 2 iterations at
50000 x 17), so set-up (building the NLP) is not counted; the build time is reported
apart. The traced (tracemalloc) solve of a large point runs 2 iterations: the peak is
reached in the first. Every point
runs in its own subprocess for a clean peak: ``resource.getrusage`` maxrss after the timed
solves, and the ``tracemalloc`` peak of a third, traced, build + solve. Sweeps: M in 500,
2000, 10000, 50000 at 5 sections and n_sections in 5, 10, 20, 40 at M = 500, for both
methods, plus the IPOPT memory case 50000 points x 17 sections. The fitted exponent of each
curve is the least-squares slope of log(time/iteration) against log(M) or log(N).

Writes ``<out>/scaling.json``, ``<out>/scaling.png`` and ``<out>/scaling.md`` (first line:
this command). Targets: time per iteration grows no faster than linearly in M (exponent
<= 1); 50000 points x 17 sections peaks under 2 GB RSS.
"""

import argparse
import json
import os
import platform
import resource
import shlex
import subprocess
import sys
import time

import numpy as np

M_SWEEP = (500, 2000, 10000, 50000)
N_SWEEP = (5, 10, 20, 40)
M_FIXED_N = 5
N_FIXED_M = 500
BIG = (50000, 17)
METHODS = ("ipopt", "barrier-lm")
ITER_LO, ITER_HI = 2, 20
ITER_HI_LARGE = 6        # iterations of the 50000 x 17 point (about 5 s each)
DELAY_MAX = 0.13          # s, example A's data-derived bound at 500 points, fixed for all M
TIMEOUT = 300             # s per point


# ----------------------------------------------------------------------------- one point


def _stage(n_points, n_sections):
    import freqid_casadi as fc
    from freqid_casadi.core.objective import Parametrization

    data = fc.systems.G_A(np.logspace(-2, 3, n_points))
    gain0 = abs(data.response[0]) * data.omega[0]
    wr = tuple(np.logspace(0, 3, n_sections))
    param = Parametrization(fc.Structure(n_sections, True, True), "dc", wr, gain0, DELAY_MAX)
    z0 = np.concatenate([[0.08, 1.0]] + [param.new_section(w, 0.01, 1.1 * w, 0.02, w)
                                         for w in wr])
    return data, param, z0


def _solver(method, funcs, param, z0, n_iter):
    """One capped solve; returns (seconds, iterations)."""
    lb, ub = param.bounds()
    t0 = time.perf_counter()
    if method == "ipopt":
        from freqid_casadi.solvers.ipopt import solve_least_squares

        res = solve_least_squares(funcs, z0, lb, ub, max_iter=n_iter)
    else:
        from freqid_casadi.solvers.barrier_lm import solve_stage_lm
        from freqid_casadi.solvers.common import StageProblem

        # the fit's barrier-LM stage: one barrier step (t = 1), n_iter LM trial steps
        res = solve_stage_lm(StageProblem.from_stage_functions(funcs, lb, ub), z0,
                             t0=1.0, t_max=1.0, max_inner=n_iter)
    return time.perf_counter() - t0, int(res.nit)


def run_point(method, n_points, n_sections):
    """Measure one point in this process (called in a fresh subprocess)."""
    import tracemalloc

    from threadpoolctl import threadpool_limits

    from freqid_casadi.core.objective import stage_functions

    rss_base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with threadpool_limits(limits=1, user_api="blas"):      # as fit() runs
        data, param, z0 = _stage(n_points, n_sections)
        t0 = time.perf_counter()
        funcs = stage_functions(param, data.omega, data.response)
        build = time.perf_counter() - t0
        large = n_points * n_sections > 200000
        iter_hi = ITER_HI_LARGE if n_points * n_sections > 500000 else ITER_HI
        _solver(method, funcs, param, z0, ITER_LO)           # warm-up (first-call costs)
        repeat = 1 if large else 2
        t_lo, it_lo = min(_solver(method, funcs, param, z0, ITER_LO) for _ in range(repeat))
        t_hi, it_hi = min(_solver(method, funcs, param, z0, iter_hi) for _ in range(repeat))
        rss_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        del funcs
        tracemalloc.start()
        funcs = stage_functions(param, data.omega, data.response)
        _solver(method, funcs, param, z0, ITER_LO if large else iter_hi)
        traced = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    d_it = it_hi - it_lo
    return dict(method=method, n_points=n_points, n_sections=n_sections,
                n_vars=int(param.n_vars), build_s=build, t_lo_s=t_lo, nit_lo=it_lo,
                t_hi_s=t_hi, nit_hi=it_hi,
                s_per_iter=(t_hi - t_lo) / d_it if d_it > 0 else t_hi / max(it_hi, 1),
                maxrss_mb=rss_peak / 1024.0, base_rss_mb=rss_base / 1024.0,
                tracemalloc_peak_mb=traced / 2 ** 20)


def _in_subprocess(method, n_points, n_sections):
    cmd = [sys.executable, os.path.abspath(__file__), "--point", method, str(n_points),
           str(n_sections)]
    t0 = time.perf_counter()
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        return dict(method=method, n_points=n_points, n_sections=n_sections,
                    error=f"timeout after {TIMEOUT} s")
    if out.returncode != 0:
        tail = out.stderr.strip().splitlines()[-1:] or ["?"]
        return dict(method=method, n_points=n_points, n_sections=n_sections,
                    error=f"exit {out.returncode}: {tail[0]}")
    row = json.loads(out.stdout.strip().splitlines()[-1])
    row["subprocess_s"] = time.perf_counter() - t0
    return row


# ----------------------------------------------------------------------------- analysis


def slope(x, y):
    """Least-squares slope of log(y) against log(x) (the fitted power-law exponent)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(y) & (y > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def _curve(rows, method, key, fixed_key, fixed):
    pts = sorted((r[key], r.get("s_per_iter", np.nan), r.get("maxrss_mb", np.nan))
                 for r in rows if r["method"] == method and r[fixed_key] == fixed
                 and "sweep" in r and r["sweep"] == key)
    return pts


def analyse(rows):
    out = {}
    for method in METHODS:
        m = _curve(rows, method, "n_points", "n_sections", M_FIXED_N)
        n = _curve(rows, method, "n_sections", "n_points", N_FIXED_M)
        out[method] = dict(
            exponent_M=slope([p[0] for p in m], [p[1] for p in m]),
            exponent_M_upper_half=slope([p[0] for p in m[-3:]], [p[1] for p in m[-3:]]),
            exponent_N=slope([p[0] for p in n], [p[1] for p in n]),
            memory_exponent_M=slope([p[0] for p in m], [p[2] for p in m]))
    return out


# ----------------------------------------------------------------------------- outputs


def _plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    for method, marker in zip(METHODS, ("o", "s")):
        m = _curve(rows, method, "n_points", "n_sections", M_FIXED_N)
        n = _curve(rows, method, "n_sections", "n_points", N_FIXED_M)
        if m:
            x, t, r = zip(*m)
            axes[0].loglog(x, np.array(t) * 1e3, marker=marker, label=method)
            axes[2].loglog(x, r, marker=marker, label=f"{method}, {M_FIXED_N} sections")
        if n:
            x, t, _ = zip(*n)
            axes[1].loglog(x, np.array(t) * 1e3, marker=marker, label=method)
    ms = np.array(M_SWEEP, float)
    ref = [r for r in rows if r.get("sweep") == "n_points" and r["method"] == "ipopt"
           and "s_per_iter" in r]
    if ref:
        t0 = ref[0]["s_per_iter"] * 1e3 / ref[0]["n_points"]
        axes[0].loglog(ms, t0 * ms, "k:", label="slope 1 (linear)")
    big = [r for r in rows if r.get("sweep") == "big" and "maxrss_mb" in r]
    for r in big:
        axes[2].loglog([r["n_points"]], [r["maxrss_mb"]], "r*", markersize=12,
                       label=f"{r['method']}, {r['n_sections']} sections")
    axes[2].axhline(2048, color="r", ls="--", lw=1, label="2 GB target")
    axes[0].set(xlabel="data points M", ylabel="ms per iteration",
                title=f"time per iteration vs M ({M_FIXED_N} sections)")
    axes[1].set(xlabel="sections N", ylabel="ms per iteration",
                title=f"time per iteration vs N (M = {N_FIXED_M})")
    axes[2].set(xlabel="data points M", ylabel="peak RSS (MB)", title="peak memory (maxrss)")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _markdown(command, rows, fits, meta):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    from freqid_casadi.report.environment import computed_on_lines
    from freqid_casadi.report.folder import generated_by_line, markdown_table

    def g(x, d=3):
        return "—" if x is None or not np.isfinite(x) else f"{x:.{d}g}"

    table = markdown_table(
        [(r.get("sweep"), r["method"], r["n_points"], r["n_sections"], r.get("n_vars"),
          g(r.get("s_per_iter", np.nan) * 1e3), r.get("nit_hi"), g(r.get("build_s", np.nan)),
          g(r.get("maxrss_mb", np.nan), 4), g(r.get("tracemalloc_peak_mb", np.nan), 4),
          r.get("error")) for r in rows],
        ("sweep", "method", "M", "N", "variables", "ms/iteration", "iterations (capped)",
         "build (s)", "peak RSS (MB)", "tracemalloc peak (MB)", "error"),
        align="llrrrrrrrrl")
    ftable = markdown_table(
        [(m, g(f["exponent_M"]), g(f["exponent_M_upper_half"]), g(f["exponent_N"]),
          g(f["memory_exponent_M"])) for m, f in fits.items()],
        ("method", "time/iter vs M", "vs M (2000..50000)", "time/iter vs N",
         "peak RSS vs M"), align="lrrrr")
    big = [r for r in rows if r.get("sweep") == "big"]
    verdict = []
    for m, f in fits.items():
        ok = np.isfinite(f["exponent_M"]) and f["exponent_M"] <= 1.05
        verdict.append(f"- {m}: time per iteration ~ M^{g(f['exponent_M'])} — "
                       f"{'meets' if ok else 'MISSES'} the target (no faster than linear).")
    for r in big:
        if "maxrss_mb" in r:
            ok = r["maxrss_mb"] < 2048
            verdict.append(f"- {r['method']} {r['n_points']} points x {r['n_sections']} "
                           f"sections: peak RSS {r['maxrss_mb']:.0f} MB — "
                           f"{'under' if ok else 'OVER'} the 2 GB target.")
        else:
            verdict.append(f"- {r['method']} {r['n_points']} x {r['n_sections']}: "
                           f"{r.get('error')}")
    return "\n".join([
        generated_by_line(command), "", "# Scaling: time per iteration and peak memory", "",
        f"System G_A (example A), integrator and delay, log grid 1e-2..1e3 rad/s; one stage "
        f"NLP per point, in its own subprocess. Time per iteration = (t({ITER_HI} it) - "
        f"t({ITER_LO} it)) / (iterations difference); IPOPT with exact Hessian, barrier-LM "
        f"with one barrier step (t = 1) and max_inner = {ITER_HI}. BLAS at one thread. "
        f"Machine: {meta['machine']}; total run {meta['total_s']:.0f} s.", "",
        *computed_on_lines(meta.get("environment")),
        "## Fitted exponents (log-log slopes)", "", ftable, "", *verdict, "",
        "## Measurements", "", table, "",
        "Peak RSS is `resource.getrusage(RUSAGE_SELF).ru_maxrss` of the point's process "
        "after the timed solves (includes the interpreter, NumPy and CasADi, about "
        f"{meta['base_rss_mb']:.0f} MB before building anything); the tracemalloc peak "
        "counts Python/NumPy allocations of a traced build + solve (CasADi's and IPOPT's "
        "C++ memory is not traced).", ""])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=None,
                        help="folder (default results/scaling; a --quick run needs its own)")
    parser.add_argument("--quick", action="store_true", help="small sizes only (smoke test)")
    parser.add_argument("--point", nargs=3, metavar=("METHOD", "M", "N"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.out is None and args.quick and not args.point:
        parser.error("--quick measures the small sizes only, which would replace the full "
                     "run's results/scaling: pass --out DIR")
    args.out = args.out or "results/scaling"
    if args.point:
        method, m, n = args.point
        print(json.dumps(run_point(method, int(m), int(n))))
        return 0

    command = " ".join(["python", "scripts/scaling.py"] + [shlex.quote(a) for a in
                                                             (argv or sys.argv[1:])])
    m_sweep = M_SWEEP[:2] if args.quick else M_SWEEP
    n_sweep = N_SWEEP[:2] if args.quick else N_SWEEP
    big = [] if args.quick else [("ipopt",) + BIG]
    plan = [("n_points", meth, m, M_FIXED_N) for meth in METHODS for m in m_sweep]
    plan += [("n_sections", meth, N_FIXED_M, n) for meth in METHODS for n in n_sweep
             if n != M_FIXED_N]
    plan += [("big", meth, m, n) for meth, m, n in big]
    t_start = time.perf_counter()
    rows = []
    for sweep, meth, m, n in plan:
        row = _in_subprocess(meth, m, n)
        row["sweep"] = sweep
        rows.append(row)
        sys.stderr.write(f"{sweep:10s} {meth:10s} M={m:6d} N={n:3d}: "
                         + (f"{row['s_per_iter'] * 1e3:8.2f} ms/it, "
                            f"RSS {row['maxrss_mb']:7.1f} MB, build {row['build_s']:.2f} s"
                            if "error" not in row else row["error"]) + "\n")
    # the n_sections sweep shares its N = 5, M = 500 point with the M sweep
    for r in list(rows):
        if r["sweep"] == "n_points" and r["n_points"] == N_FIXED_M and "error" not in r:
            rows.append({**r, "sweep": "n_sections"})
    rows.sort(key=lambda r: (("n_points", "n_sections", "big").index(r["sweep"]),
                             r["method"], r["n_points"], r["n_sections"]))
    fits = analyse(rows)
    base = [r["base_rss_mb"] for r in rows if "base_rss_mb" in r]
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    from freqid_casadi.report.environment import environment

    meta = dict(machine=f"{platform.processor() or platform.machine()}, "
                        f"{os.cpu_count()} cores, Python {platform.python_version()}",
                total_s=time.perf_counter() - t_start, environment=environment(),
                base_rss_mb=float(np.median(base)) if base else float("nan"))
    os.makedirs(args.out, exist_ok=True)
    from freqid_casadi.report.folder import atomic_write_text

    payload = dict(command=command, meta=meta, exponents=fits, rows=rows,
                   settings=dict(iter_lo=ITER_LO, iter_hi=ITER_HI, delay_max=DELAY_MAX,
                                 m_sweep=list(m_sweep), n_sweep=list(n_sweep),
                                 big=[list(b) for b in big]))
    atomic_write_text(os.path.join(args.out, "scaling.json"),
                      json.dumps(payload, indent=1, default=float) + "\n")
    png = os.path.join(args.out, "scaling.png")
    tmp = png + ".tmp.png"
    _plot(rows, tmp)
    os.replace(tmp, png)
    atomic_write_text(os.path.join(args.out, "scaling.md"),
                      _markdown(command, rows, fits, meta))
    mask = os.umask(0o022)                 # atomic_write_text leaves 0600: use the umask
    os.umask(mask)
    for name in ("scaling.json", "scaling.md", "scaling.png"):
        os.chmod(os.path.join(args.out, name), 0o666 & ~mask)
    for meth, f in fits.items():
        print(f"{meth}: time/iter ~ M^{f['exponent_M']:.2f} (2000..50000: "
              f"M^{f['exponent_M_upper_half']:.2f}), ~ N^{f['exponent_N']:.2f}")
    for r in rows:
        if r["sweep"] == "big":
            print(f"{r['method']} {r['n_points']} x {r['n_sections']}: peak RSS "
                  f"{r.get('maxrss_mb', float('nan')):.0f} MB")
    print(f"total {meta['total_s']:.0f} s; wrote {args.out}/scaling.{{json,png,md}}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

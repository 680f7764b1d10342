"""Time of the sweep of example A over orders 2:40:2 and its monotonicity (issue 14).

Usage::

    python scripts/sweep_benchmark.py [--orders 2:40:2]

Prints the wall time of ``sweep(G_A(), orders, integrator=True)``, the machine's load
average before and after (the 2-core machine is shared: times are noisy), the max relative
error per order and whether it is non-increasing (N+1 sections never worse than N), and,
as a baseline measured in the same run, the wall time of the same fits one by one with
``IpoptOptions(ftol=0)`` (IPOPT's own tolerance only, the stage termination before issue
14), ``LoopOptions(init="peak")`` (no relocation) and no extension start. Target: <= 15 s, error non-increasing.
"""

import argparse
import os
import sys
import time
import warnings

import freqid_casadi as fc
from freqid_casadi.sweep import parse_orders, sweep


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", default="2:40:2")
    ap.add_argument("--no-baseline", action="store_true")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", fc.errors.ResolutionWarning)
    data = fc.systems.G_A()
    orders = parse_orders(args.orders)
    print(f"load average before: {os.getloadavg()}")
    t0 = time.perf_counter()
    res = sweep(data, orders, integrator=True)
    t_now = time.perf_counter() - t0
    print(f"sweep A {args.orders}: {t_now:.1f} s; load average after: {os.getloadavg()}")
    for r in res.rows:
        print(f"  order {r.order:3d}: max rel. error {r.max_rel_error:.3e} ({r.start}, "
              f"success {r.success}, {r.wall_time:.2f} s)")
    errs = [r.max_rel_error for r in res.rows]
    mono = all(b <= a for a, b in zip(errs, errs[1:]))
    print(f"non-increasing with order: {mono}; target <= 15 s: "
          f"{'met' if t_now <= 15 else 'MISSED'} ({t_now:.1f} s)")
    if not args.no_baseline:
        t0 = time.perf_counter()
        base = [fc.fit(data, n_sections=o // 2, integrator=True,
                       method=fc.IpoptOptions(ftol=0.0),
                       loop=fc.LoopOptions(init="peak")).max_rel_error for o in orders]
        t_base = time.perf_counter() - t0
        inc = sum(1 for a, b in zip(base, base[1:]) if b > a)
        print(f"baseline (fits one by one, ftol=0): {t_base:.1f} s, error increases at {inc} "
              f"of {len(orders) - 1} steps; ratio now/baseline {t_now / t_base:.2f}; load "
              f"average {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Where a final stage creeps to: the path of a fit's variables when its last stage goes on.

Usage::

    python scripts/final_stage_path.py [--example C] [--start rational] [--chunks 10]
                                       [--chunk-iter 300] [--delay H]

Fits the example at the thesis's order (``fc.fit``, ``start`` as given), or, with
``--delay H``, takes the rational start's vector fit at the single trial delay ``H`` (s),
and then continues the final stage from that model in ``--chunks`` polishes of
``--chunk-iter`` IPOPT iterations each (:func:`freqid_casadi.fitting.stages.polish`, the rational
start's last stage). After each chunk it prints the stage cost, the max relative error,
the delay, the stage's end message and the three sections whose roots moved most (relative
change of natural frequency or damping ratio). At the end it prints every section's roots
at the start and at the end (natural frequency rad/s / damping ratio of numerator and
denominator), and the negative-curvature directions of the exact Hessian there (Jacobi
scaled, divided by the cost, variables held at a bound and exactly cancelling sections
left out), named by section variable. Prints only; writes nothing.

This is the measurement behind the strict xfails of example C in tests/test_relocate.py
(issue 14).
"""

import argparse
import warnings

import numpy as np

import freqid_casadi as fc
from freqid_casadi.systems.examples import EXAMPLES
from freqid_casadi.core.objective import stage_functions
from freqid_casadi.fitting.stages import polish, stage_cost


def _roots(model):
    """(N, 4): natural frequency and damping ratio of every numerator and denominator."""
    out = []
    for a, zn, wn, b, zd, wd in model.sections():
        row = []
        for c, z, w in ((a, zn, wn), (b, zd, wd)):
            row += [w / np.sqrt(c), z / np.sqrt(c)] if c > 0 else [np.inf, z]
        out.append(row)
    return np.array(out)


def _moved(before, after, top=3):
    """The ``top`` sections whose roots moved most (largest relative change; a damping
    ratio's change relative to at least 1e-3, so a root the barrier holds at 1e-14 off
    the imaginary axis does not count)."""
    scale = np.abs(before)
    scale[:, 1::2] = np.maximum(scale[:, 1::2], 1e-3)
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.nan_to_num(np.abs(after - before) / scale, nan=0.0, posinf=0.0)
    order = np.argsort(-rel.max(axis=1))[:top]
    return ", ".join(f"s{k} x{1 + rel[k].max():.3g}" for k in order)


def _names(n_sections):
    return ["h", "K"] + [f"s{k}.{v}" for k in range(n_sections) for v in ("p2", "p1", "q2", "q1")]


def _curvature(pol, data, n_dirs=4):
    """Print the negative eigen-directions of the Jacobi-scaled Hessian / cost at the end."""
    param, z = pol.param, pol.x
    funcs = stage_functions(param, data.omega, data.response)
    lb, ub = param.bounds()
    _, jac = funcs.residual_jacobian(z)
    jac = np.asarray(jac)
    cost, grad = funcs.gradient(z)
    hess = np.asarray(funcs.hessian(z))
    cn = np.linalg.norm(jac, axis=0)
    held = ((z - lb) * cn < 1e-4 * np.sqrt(cost)) & (grad > 0)
    roots = _roots(param.to_model(z))
    cancel = np.isclose(roots[:, 0], roots[:, 2], rtol=1e-4) & np.isclose(
        roots[:, 1], roots[:, 3], rtol=1e-4)
    free = ~held & (lb < ub) & (cn > 0)
    for k in np.flatnonzero(cancel):
        free[2 + 4 * k: 6 + 4 * k] = False
    d = 1.0 / cn[free]
    h = hess[np.ix_(free, free)] * d[:, None] * d[None, :] / cost
    ev, vec = np.linalg.eigh(h)
    names = np.array(_names(param.structure.n_sections))[free]
    cos = np.abs(grad[free]) * d / (2 * np.sqrt(cost))
    print(f"\nat the end: cost {cost:.4g}; held at a bound: "
          f"{', '.join(np.array(_names(param.structure.n_sections))[held]) or '-'}; "
          "exactly cancelling sections: "
          f"{', '.join(f's{k}' for k in np.flatnonzero(cancel)) or '-'}")
    print(f"max cos(r, J_j) over the other variables {cos.max():.3g} "
          f"({names[np.argmax(cos)]}); Hessian/cost (Jacobi): {int(np.sum(ev < 0))} negative "
          f"eigenvalues, min {ev[0]:.3g}, max {ev[-1]:.3g}")
    for i in range(min(n_dirs, int(np.sum(ev < 0)))):
        top = np.argsort(-np.abs(vec[:, i]))[:6]
        print(f"  {ev[i]:10.3g}: " + ", ".join(f"{names[j]} {vec[j, i]:+.2f}" for j in top))


def _start_model(ex, args, data):
    if args.delay is None:
        res = fc.fit(data, start=args.start, **ex.structure())
        print(f"fit(start={args.start!r}): {res.nit} IPOPT its, max rel. error "
              f"{res.max_rel_error:.3g}, delay {res.delay:.7g} s, success {res.success}")
        return res.model, res.delay_max
    from freqid_casadi.core.resolution import default_delay_max
    from freqid_casadi.fitting.start import rational_start

    delay_max = max(default_delay_max(data.omega), args.delay)
    rs = rational_start(data, fc.Structure(ex.n_sections, ex.integrator, ex.delay),
                        delay_max=delay_max, delay0=args.delay, max_delay_updates=1)
    print(f"vector fit at h = {args.delay:.7g} s: max rel. error {rs.max_rel_error:.3g}")
    return rs.model, delay_max


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--example", default="C", choices=["A", "B", "C"])
    ap.add_argument("--start", default="rational", choices=["rational", "sequential"])
    ap.add_argument("--chunks", type=int, default=10)
    ap.add_argument("--chunk-iter", type=int, default=300)
    ap.add_argument("--delay", type=float, default=None)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", fc.errors.ResolutionWarning)
    ex = EXAMPLES[args.example]
    data = ex.system()
    model, delay_max = _start_model(ex, args, data)
    first = _roots(model)
    total = 0
    for i in range(args.chunks):
        before = _roots(model)
        pol = polish(model, data, max_iter=args.chunk_iter, delay_max=delay_max)
        model, total = pol.model, total + pol.result.nit
        err = float(np.max(model.relative_error(data)))
        print(f"{total:6d} its: cost {stage_cost(pol.param, data, pol.x):.4e}, max {err:.3e}, "
              f"h {model.delay:.7f} s; moved most: {_moved(before, _roots(model))}; "
              f"{pol.result.message[:90]}")
    last = _roots(model)
    print("\nsection: start num w/zeta  den w/zeta  ->  end num w/zeta  den w/zeta (rad/s)")
    for k, (a, b) in enumerate(zip(first, last)):
        print(f"s{k:<3d}" + "  ->  ".join(f"{r[0]:9.4g}/{r[1]:<8.3g} {r[2]:9.4g}/{r[3]:<8.3g}"
                                          for r in (a, b)))
    _curvature(pol, data)


if __name__ == "__main__":
    main()

"""Check of the choices a fit of many points settles on a subset of them.

Above :data:`~freqid_casadi.fitting.core_fits.SETTLE_ABOVE` frequencies the rational
starts that choose the contenders of ``integrator="auto"`` (the pole counts at the origin
they leave undecided) see :data:`~freqid_casadi.fitting.core_fits.SETTLE_POINTS` of the
points, the contenders and the two gain signs where the starts do not decide the sign are
fitted on them, and the kept k or sign on all. This script measures what that changes:
the validation corpus's systems (``freqid_casadi.systems.corpus.case``, seed 0) sampled
at ``--points`` frequencies over each case's band and spacing, with its noise profile
interpolated (complex Gaussian relative noise, seeded per case), each fitted with the
default options twice in one worker process, one right after the other: with the subset,
then with the starts, contenders and signs on all points (``SETTLE_ABOVE`` raised beyond
the data: the code path before the subset).

Usage::

    python scripts/settle_check.py [--points 20000] [--cases 0:300:10] [--workers 2]
                                   [--out results]

``--cases`` takes ``start:stop:step`` or a comma-separated list of case indices.

Writes ``<out>/settle_check.md`` (first line: this command) and ``<out>/settle_check.json``.
"""

import argparse
import json
import math
import multiprocessing
import os
import sys
import time
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import freqid_casadi as fc  # noqa: E402
from freqid_casadi.fitting import core_fits  # noqa: E402
from freqid_casadi.fitting import fit as fit_module  # noqa: E402
from freqid_casadi.report.environment import computed_on_lines, environment  # noqa: E402
from freqid_casadi.report.folder import atomic_write_text  # noqa: E402
from freqid_casadi.systems.corpus import case  # noqa: E402


def dense_case(index, points):
    """``(case, FrequencyData)``: case ``index`` (seed 0) sampled at ``points``
    frequencies over its band (log or linear, as the case), its noise profile
    interpolated in log frequency, the noise seeded by the index
    (:meth:`~freqid_casadi.systems.corpus.CorpusCase.resampled`)."""
    c = case(index, 0, max_points=5000)
    return c, c.resampled(points, np.random.default_rng(1000 + index))


def _fit(data, n_sections):
    signs = []                 # what each settle of the gain sign on the subset gave
    settle = fit_module.sign_on_subset

    def counted(*args):
        found = settle(*args)
        signs.append(None if found is None else int(found[0]))
        return found

    fit_module.sign_on_subset = counted
    t0 = time.process_time()
    try:
        res = fc.fit(data, n_sections=n_sections)
    finally:
        fit_module.sign_on_subset = settle
    rec = res.details.get("integrator", {})
    return {"cpu": time.process_time() - t0, "signs": signs, "k": int(res.model.origin_order),
            "sign": int(res.model.structure.gain_sign), "rms": float(res.rms_rel_error),
            "max": float(res.max_rel_error), "status": str(res.status.value),
            "contenders": rec.get("contenders"), "settled_on": rec.get("settled_on"),
            "beta": [float(b) for b in res.model.beta]}


def check_case(task):
    """One case: the fit with the subset, then on all points (main() takes only
    ``--points`` above SETTLE_ABOVE, so every case has both)."""
    index, points = task
    warnings.simplefilter("ignore")
    c, data = dense_case(index, points)
    row = {"index": index, "name": c.name, "spacing": c.spacing,
           "n_sections": int(c.n_sections)}
    try:
        row["subset"] = _fit(data, c.n_sections)
        above = core_fits.SETTLE_ABOVE
        core_fits.SETTLE_ABOVE = math.inf
        try:
            row["all"] = _fit(data, c.n_sections)
        finally:
            core_fits.SETTLE_ABOVE = above
    except Exception as exc:                       # noqa: BLE001 (reported, not hidden)
        row["error"] = f"{type(exc).__name__}: {exc}"
    print(f"  {c.name}: {row.get('subset', {}).get('cpu', math.nan):.1f} s"
          + (f" / {row['all']['cpu']:.1f} s" if "all" in row else ""), file=sys.stderr)
    return row


def summary(rows):
    several = [r for r in rows if "all" in r]
    same = [r for r in several if r["subset"]["beta"] == r["all"]["beta"]
            and r["subset"]["status"] == r["all"]["status"]]
    ratios = np.array([r["subset"]["cpu"] / r["all"]["cpu"] for r in several])
    out = {"cases": len(rows), "errors": sum("error" in r for r in rows),
           "several": len(several), "same": len(same),
           "settled": sum(bool(r["subset"]["settled_on"]) for r in several),
           "signs_tried": sum(len(r["subset"]["signs"]) for r in several),
           "signs_settled": sum(x is not None for r in several for x in r["subset"]["signs"])}
    if several:
        out.update(cpu_subset=float(sum(r["subset"]["cpu"] for r in several)),
                   cpu_all=float(sum(r["all"]["cpu"] for r in several)),
                   ratio_quartiles=[float(q) for q in np.percentile(ratios, [25, 50, 75])],
                   ratio_max=float(ratios.max()), slower=int(np.sum(ratios > 1)))
    return out


def _signs(a):
    """The sign settles of one fit: each subset's kept sign, "-" where it fell back."""
    return ", ".join("-" if x is None else f"{x:+d}" for x in a["signs"]) or "none"


def markdown(command, points, rows, s, env):
    lines = [f"<!-- generated by: {command} -->", "",
             "# Choices settled on a subset of many points", "",
             *computed_on_lines(env),
             f"The corpus's systems sampled at {points} frequencies (above SETTLE_ABOVE = "
             f"{core_fits.SETTLE_ABOVE}), each fitted with the default options with the "
             f"subset ({core_fits.SETTLE_POINTS} points: the rational starts that choose "
             "integrator='auto''s contenders, the contenders' fits, and both gain signs where "
             "the starts leave the sign undecided) and with all of them on all points, in one "
             "process one after the other. "
             "`contenders`: integrator='auto''s; `settled on`: where they were settled; "
             "`gain signs on the subset`: each settle of the sign the fit tried (its core "
             "fit's and its refits'), the kept sign or \"-\" where the subset did not "
             "decide. CPU seconds.", "",
             "| case | contenders | settled on | gain signs on the subset | k (subset / all) "
             "| RMS (subset / all) | status | same bits | CPU subset (s) | CPU all (s) |",
             "|---|---|---|---|---|---|---|---|---:|---:|"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['name']} | {r['error']} | | | | | | | | |")
            continue
        a, b = r["subset"], r.get("all")
        on = a["settled_on"]
        lines.append(
            f"| {r['name']} | {a['contenders']} | "
            + (f"{on['points']} of {on['of']}" if on else "all points") + f" | {_signs(a)} | "
            + (f"{a['k']} / {b['k']} | {a['rms']:.4g} / {b['rms']:.4g} | {a['status']} / "
               f"{b['status']} | {'yes' if a['beta'] == b['beta'] else 'no'} | "
               f"{a['cpu']:.1f} | {b['cpu']:.1f} |" if b else
               f"{a['k']} | {a['rms']:.4g} | {a['status']} | (one path) | {a['cpu']:.1f} | |"))
    lines += ["", f"Cases: {s['cases']} ({s['errors']} errors); fitted both ways (a subset "
              f"tried): {s['several']}, of which the contenders settled on the subset: "
              f"{s['settled']}; settles of the gain sign tried: {s['signs_tried']}, decided "
              f"on the subset: {s['signs_settled']}; the same model and status to the last "
              f"bit: {s['same']} of {s['several']}."]
    if s["several"]:
        q = s["ratio_quartiles"]
        lines += ["", f"CPU of the cases fitted both ways: {s['cpu_all']:.0f} s with the "
                  f"contenders and signs on all points, {s['cpu_subset']:.0f} s with the "
                  f"subset ({s['cpu_subset'] / s['cpu_all']:.2f}); per case the ratio's "
                  f"quartiles {q[0]:.2f}, {q[1]:.2f}, {q[2]:.2f}, at most "
                  f"{s['ratio_max']:.2f}; {s['slower']} took longer with the subset."]
    return "\n".join(lines) + "\n"


def case_indices(ap, text):
    """The case indices of a ``--cases`` argument: ``start:stop:step`` or ``i,j,k``
    (``ap.error`` otherwise)."""
    try:
        return (range(*(int(x) for x in text.split(":"))) if ":" in text
                else [int(x) for x in text.split(",")])
    except (TypeError, ValueError):
        ap.error(f"--cases takes start:stop:step or i,j,k, got {text!r}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=20_000)
    ap.add_argument("--cases", default="0:300:10",
                    help="start:stop:step of case indices, or a comma-separated list")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="results")
    args = ap.parse_args(argv)
    indices = case_indices(ap, args.cases)
    if args.points <= core_fits.SETTLE_ABOVE:
        ap.error(f"--points must exceed SETTLE_ABOVE = {core_fits.SETTLE_ABOVE}")
    tasks = [(i, args.points) for i in indices]
    command = "python scripts/settle_check.py" + "".join(
        f" --{k} {v}" for k, v in (("points", args.points), ("cases", args.cases),
                                   ("workers", args.workers), ("out", args.out))
        if v != ap.get_default(k))
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        rows = pool.map(check_case, tasks, chunksize=1)
    s = summary(rows)
    text = markdown(command, args.points, rows, s, environment())
    os.makedirs(args.out, exist_ok=True)
    atomic_write_text(os.path.join(args.out, "settle_check.md"), text)
    atomic_write_text(os.path.join(args.out, "settle_check.json"), json.dumps(
        {"command": command, "points": args.points, "summary": s, "rows": rows},
        indent=1) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

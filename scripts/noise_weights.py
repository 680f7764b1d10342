"""fit(weights="noise") on corpus systems: without weights, estimated, the true weights.

Usage::

    python scripts/noise_weights.py [--seed 53] [--cases 80] [--max-points 300]
                                    [--kinds floor,mixed,relative] [--out results/noise-weights]
                                    [--force]

Runs :mod:`freqid_casadi.studies.noise_weights` (three fits of every in-class noisy case
of the first ``--cases`` corpus indices, for each noise kind, in 2 processes) and writes
``report.md`` (first line: this command) and ``report.json`` (every fit's numbers).
"""

import argparse
import os
import shlex
import sys
import time

from freqid_casadi.errors import FreqidError
from freqid_casadi.report.environment import computed_on_lines, environment
from freqid_casadi.report.folder import check_out_dir, write_study_report
from freqid_casadi.report.formatting import generated_by_line, json_safe, markdown_table
from freqid_casadi.studies.noise_weights import KINDS, WAYS, run_study, summarise

_WAYS = {"none": "without weights", "noise": "weights='noise'", "true": "true weights"}
_KINDS = {"floor": "a noise floor (constant absolute level, 0.3-3 % of the median |G|)",
          "mixed": "a noise floor plus 0.1-1 % relative noise",
          "relative": "the corpus's relative noise (flat or sloped up to 10-fold)"}


def render(command, s):
    """The Markdown text of report.md from the content of report.json."""
    lines = [generated_by_line(command), "", "# weights='noise' on corpus systems", ""]
    lines += computed_on_lines(s.get("environment"))
    lines += [f"In-class noisy cases of corpus seed {s['seed']} (indices 0-{s['cases'] - 1}, "
              f"at most {s['max_points']} points), each fitted at its true order without "
              "weights, with `weights='noise'` and with the true inverse relative variances. "
              "`error`: the model's error against the true system in units of the true "
              "noise, `sqrt(mean |G_N/G - 1|^2 / sigma^2)` (0.1-0.3 at the noise floor); "
              "`vs none`: the geometric mean of its ratio to the fit without weights; "
              "`worse`: fits more than 1.5 times worse than without weights; `ok far`: "
              f"fits whose status is ok more than 2 noise units from the truth. "
              f"{s['seconds']:.0f} s.", ""]
    for kind, ways in s["summary"].items():
        lines += [f"## {_KINDS.get(kind, kind)}", ""]
        rows = [(_WAYS[w], v["cases"], f"{v['ratio_geomean']:.3g}", f"{v['median_error']:.3g}",
                 v["worse"], v["ok"], v["poor_fit"], v["not_converged"],
                 f"{len(v['ok_far'])} {', '.join(v['ok_far'])}".strip(), f"{v['cpu']:.0f}")
                for w, v in ways.items()]
        lines += [markdown_table(rows, ("fit", "cases", "error vs none", "median error",
                                        "worse", "ok", "poor-fit", "not-converged",
                                        "ok far", "CPU s"),
                                 align="lrrrrrrrlr"), ""]
    return "\n".join(lines)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=53)
    ap.add_argument("--cases", type=int, default=80)
    ap.add_argument("--max-points", type=int, default=300)
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--out", default=os.path.join("results", "noise-weights"))
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    kinds = [k for k in args.kinds.split(",") if k]
    if not kinds or any(k not in KINDS for k in kinds):
        ap.error(f"--kinds: a comma-separated list of {', '.join(KINDS)}")
    command = " ".join(["python scripts/noise_weights.py"] + [shlex.quote(a) for a in argv])
    try:
        check_out_dir(args.out, args.force)
        t0 = time.perf_counter()

        def progress(row):
            print(f"{row['kind']} {row['case']}: " + "; ".join(
                f"{w} {row[w]['status']} {row[w]['error']:.3g}" for w in WAYS), flush=True)

        rows = run_study(kinds, args.seed, args.cases, args.max_points, progress=progress)
        s = json_safe({"command": command, "seed": args.seed, "cases": args.cases,
                       "max_points": args.max_points, "seconds": time.perf_counter() - t0,
                       "summary": summarise(rows), "rows": rows,
                       "environment": environment()})
        write_study_report(args.out, s, render(command, s), force=args.force)
    except (FreqidError, OSError) as exc:
        sys.stderr.write(f"error: {' '.join(str(exc).split())}\n")
        return 2
    print(f"report: {os.path.join(args.out, 'report.md')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""fit_shared on random modal tests, with minimum-phase and with free zeros in every channel.

Usage::

    python scripts/modal_zeros.py [--seed 0] [--cases 32] [--points 300]
                                  [--out results/modal-zeros] [--force]

Runs :mod:`freqid_casadi.studies.modal_zeros` (each case fitted at its true order with
``zeros="minimum-phase"`` and ``zeros="free"``, delay none, in 2 processes) and writes
``report.md`` (first line: this command) and ``report.json`` (every fit's numbers). The
numbers behind ``freqid modal``'s default ``--zeros free``.
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
from freqid_casadi.studies.modal_zeros import (CHOICES, DAMPING_TOL, FREQ_TOL, MAC_TOL,
                                               run_study, summarise)


def render(command, s):
    """The Markdown text of report.md from the content of report.json."""
    lines = [generated_by_line(command), "", "# Shared-pole fits of modal tests: the "
             "channels' zeros", ""]
    lines += computed_on_lines(s.get("environment"))
    lines += [f"{s['cases']} random modal tests (`freqid_casadi.studies.modal_zeros."
              f"modal_case`, seed {s['seed']}): 2-5 modes (natural frequencies 1.3-3 times "
              "apart, damping 0.5-3 %), 3-6 sensors of which the first is at the drive "
              "(collocated, minimum phase) and the others at shapes drawn uniformly in "
              f"[-1, 1], {s['points']} log-spaced points, 0.3-2 % complex Gaussian relative "
              "noise. Each is fitted by `fit_shared` at its true order, delay none, once "
              "with every channel's zeros minimum phase and once free. A fit **finds the "
              f"modes** when every natural frequency is within {100 * FREQ_TOL:g} %, every "
              f"damping ratio within {100 * DAMPING_TOL:g} % and the MAC of every mode's "
              f"residue vector (the fitted models' `Mode.residues`) against the truth above "
              f"{MAC_TOL}; `mode_shapes()`, whose modal constants are re-estimated by least "
              "squares at the fit's poles, gives shapes closer to the truth than a poor "
              f"model's residues. {s['seconds']:.0f} s.", ""]
    names = {"minimum-phase": "minimum phase", "free": "free"}
    rows = [(names[c], v["cases"], v["found"], v["ok"],
             f"{len(v['ok_not_found'])} {', '.join(map(str, v['ok_not_found']))}".strip(),
             f"{v['median_freq_error']:.2g}", f"{v['median_damping_error']:.2g}",
             f"{v['median_min_mac']:.4f}", f"{v['offered']} of {v['not_ok']}",
             f"{v['cpu']:.0f}") for c, v in s["summary"].items()]
    lines += [markdown_table(rows, ("zeros", "cases", "modes found", "status ok",
                                    "ok, modes not found", "median freq. error",
                                    "median damping error", "median least MAC",
                                    "free zeros offered (of not ok)", "CPU s"),
                             align="lrrrlrrrrr"), ""]
    mp = s["summary"].get("minimum-phase", {})
    if mp:
        lines += [f"A minimum-phase fit that is not \"ok\" is fitted again with free zeros "
                  f"and offers that fit in its message when it is \"ok\" or halves the worst "
                  f"channel's RMS error (`SharedFitResult.details[\"free_zeros\"]`); the "
                  f"offers named the collocated channel among those with right-half-plane "
                  f"zeros in {mp['offer_names_collocated']} cases.", ""]
    lines += ["Every fit:", ""]
    rows = [(r["case"], r["modes"], r["channels"], f"{100 * r['noise']:.2g} %",
             *(f"{r[c]['status']}, {r[c]['freq_error']:.1e} / {r[c]['damping_error']:.1e}"
               f" / {r[c]['min_mac']:.4f}" for c in CHOICES)) for r in s["rows"]]
    lines += [markdown_table(rows, ("case", "modes", "sensors", "noise",
                                    *(f"{names[c]}: status, freq. / damping error / MAC"
                                      for c in CHOICES)), align="rrrrll"), ""]
    return "\n".join(lines)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases", type=int, default=32)
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--out", default=os.path.join("results", "modal-zeros"))
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    command = " ".join(["python scripts/modal_zeros.py"] + [shlex.quote(a) for a in argv])
    try:
        check_out_dir(args.out, args.force)
        t0 = time.perf_counter()

        def progress(row):
            print(f"case {row['case']}: " + "; ".join(
                f"{c} {row[c]['status']} {row[c]['freq_error']:.2g}" for c in CHOICES),
                flush=True)

        rows = run_study(args.cases, args.seed, args.points, progress=progress)
        s = json_safe({"command": command, "seed": args.seed, "cases": args.cases,
                       "points": args.points, "seconds": time.perf_counter() - t0,
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

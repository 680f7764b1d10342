"""The automatic order's rule judged on many noisy corpus cases, from one fit per order.

Usage::

    python scripts/corpus_order.py [--rounds 0,8,16,...] [--seed 0]
                                   [--max-points 120] [--many-modes 24] [--workers 2]
                                   [--out DIR] [--force]

Fits every noisy case of the given rounds of the nine families (round r: corpus indices
9 r ... 9 r + 8; rounds 0, 8, 16, 24 and 32 are the corpus run's automatic-order subset)
and ``--many-modes`` lightly damped structures of 6-16 modes at 400 points
(``freqid_casadi.studies.corpus_order.many_mode_case``; the corpus's families have at most
6) at 1 ... true + 3 sections, at most 16 (``freqid_casadi.studies.corpus_order.ladder``; each case's
ladder is appended to ``DIR/ladders.jsonl`` as it ends, and a run started again fits only
the missing ones), then replays each rule of ``freqid_casadi.studies.corpus_order.RULES``
over the ladders -- the rule of ``n_sections="auto"`` as ``choose_order`` applies it to
live fits -- and writes ``DIR/report.md`` (first line: this command) and ``DIR/report.json``:
per rule, the fraction of cases whose chosen order lies in [true, true + 1], on the
corpus run's subset and on the other rounds, by family, and every miss with its orders.
Default ``--out``: results/corpus-order.
"""

import argparse
import json
import os
import shlex
import sys
import time

from freqid_casadi.report.environment import computed_on, environment
from freqid_casadi.report.folder import generated_by_line, markdown_table
from freqid_casadi.studies.corpus_order import (EXTRA, MANY_MODES, RULES, SUBSET_ROUNDS,
                                                judge, many_mode_tasks, order_tasks,
                                                run_ladders)


def _line(d):
    def one(o):
        if "rms" not in o:
            return f"{o['n_sections']}: {o['error'].split(':')[0]}"
        free = (f" [free zeros {o['free']['rms']:.3g} (x{o['free']['ratio']:.2g})]"
                if "free" in o else "")
        return f"{o['n_sections']}: {o['rms']:.3g} (x{o['ratio']:.2g}){free}"
    return " ".join(one(o) for o in d["orders"])


def report(command, ladders, rounds, seed, max_points, wall):
    """Markdown lines and the JSON dict of the comparison."""
    verdicts = {name: judge(ladders, rule, **opts) for name, (rule, _, opts) in RULES.items()}
    env = environment()
    md = [generated_by_line(command), "",
          "# The automatic order on the noisy corpus cases (issue 26, item 6)", "",
          f"{sum(d['family'] != 'many-modes' for d in ladders)} noisy cases of corpus seed "
          f"{seed} (rounds {', '.join(map(str, rounds))} of the nine families, at most "
          f"{max_points} points) and {sum(d['family'] == 'many-modes' for d in ladders)} "
          f"lightly damped structures of {min(MANY_MODES)}-{max(MANY_MODES)} modes "
          "(`many_mode_case`: collocated, 0.3-3 % noise, 400 points; the corpus's families "
          f"have at most 6 modes), each fitted once at 1 ... true + {EXTRA} sections (at "
          "most 16) with today's other defaults; "
          "each rule is replayed over those fits exactly as `n_sections=\"auto\"` applies it "
          "(`freqid_casadi.studies.corpus_order`). The subset: rounds "
          f"{', '.join(map(str, SUBSET_ROUNDS))}, the cases of results/corpus's automatic-"
          f"order table. {wall:.0f} s of fitting in this invocation.", "",
          computed_on(env), "",
          "## Order in [true, true + 1]", ""]
    rows = []
    for name in RULES:
        v = [x for x in verdicts[name] if x["family"] != "many-modes"]
        many = [x for x in verdicts[name] if x["family"] == "many-modes"]
        for label, sel in (("subset", [x for x in v if x["subset"]]),
                           ("other rounds", [x for x in v if not x["subset"]]),
                           ("all", v),
                           ("all, true order at the floor", [x for x in v if x["floor"]]),
                           ("many modes", many),
                           ("many modes, true order at the floor",
                            [x for x in many if x["floor"]])):
            if not sel:
                continue
            hit = sum(x["right"] for x in sel)
            rows.append((name, label, len(sel), f"{hit} ({100 * hit / len(sel):.1f} %)",
                         sum(x["below"] for x in sel), sum(x["above"] for x in sel)))
    md += [markdown_table(rows, ["rule", "cases", "n", "in [true, true+1]", "below",
                                 "above"], "llrrrr"), "",
           "\"At the floor\": the fit at the true order reaches RMS <= 1.5 x the noise; "
           "outside those cases the order search cannot find the true order whatever its "
           "rule (a fit that fails at that order, or a system outside the minimum-phase "
           "class).", ""]
    for name, (_, text, _) in RULES.items():
        md += [f"**{name}**: {text}", ""]
    md += ["## Misses", "", "Each rule's cases outside [true, true + 1]: the order chosen, "
           "why, and every order's RMS (x its roughness ratio; in brackets the zeros='free' "
           "model the fit offers, when it offers one).", ""]
    by_case = {d["case"]: d for d in ladders}
    for name in RULES:
        miss = [x for x in verdicts[name] if not x["right"]]
        md += [f"### {name}", "",
               markdown_table([(x["case"], x["true"], x["chosen"] if x["chosen"] else "–",
                                x["reason"], "yes" if x["subset"] else "",
                                _line(by_case[x["case"]])) for x in miss],
                              ["case", "true", "chosen", "reason", "subset", "orders"],
                              "lrrlll") if miss else "none.", ""]
    js = {"command": command, "seed": seed, "rounds": list(rounds), "max_points": max_points,
          "rules": {n: t for n, (_, t, _) in RULES.items()}, "verdicts": verdicts,
          "environment": env}
    return md, js


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", default="0,8,16,24,32,4,12,20,28,2,6,10,14,18,22,26,30",
                    help="rounds of the nine families (default: the even rounds of the "
                         "300-case corpus, the subset first)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-points", type=int, default=120)
    ap.add_argument("--many-modes", type=int, default=24,
                    help="many-mode structures fitted beside the corpus cases (default 24)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=os.path.join("results", "corpus-order"))
    ap.add_argument("--force", action="store_true", help="fit every ladder again")
    args = ap.parse_args(argv)
    try:
        rounds = [int(r) for r in args.rounds.split(",")]
    except ValueError:
        ap.error(f"--rounds must be integers separated by commas, got {args.rounds!r}")
    command = " ".join(["python scripts/corpus_order.py"] + [shlex.quote(a) for a in argv])
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "ladders.jsonl")
    if args.force and os.path.exists(path):
        os.remove(path)
    t0 = time.perf_counter()

    def progress(d):
        print(f"{d['case']}: true {d['true_sections']}, {_line(d)}", file=sys.stderr,
              flush=True)
    tasks = order_tasks(args.seed, rounds, args.max_points)
    tasks += many_mode_tasks(args.many_modes, args.seed)
    ladders = run_ladders(tasks, path, args.workers, progress)
    md, js = report(command, ladders, rounds, args.seed, args.max_points,
                    time.perf_counter() - t0)
    for name, text in (("report.md", "\n".join(md) + "\n"),
                       ("report.json", json.dumps(js, indent=1))):
        tmp = os.path.join(args.out, name + ".tmp")
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, os.path.join(args.out, name))
    print(f"report: {os.path.join(args.out, 'report.md')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

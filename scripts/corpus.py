"""The validation corpus: today's defaults and the candidates on seeded synthetic FRFs.

Usage::

    python scripts/corpus.py [--quick] [--n N] [--seed S] [--workers W] [--out DIR]
                             [--force] [--resume] [--rerender DIR]
                             [--measured | --no-measured | --measured-only]

Fits every case of ``freqid_casadi.systems.corpus(n, seed)`` at its true order with each
configuration of ``freqid_casadi.studies.corpus.CONFIGS`` and the noisy cases with
``n_sections="auto"``, on ``--workers`` processes (default 2), a progress line per fit on
stderr. Writes ``--out`` (default ``results/corpus``; ``--quick``: 60 cases of at most 400
points into ``results/corpus-quick``): report.md (first line: this command), report.json,
fits.csv and corpus.png. Each fit is also appended to ``OUT.checkpoint.jsonl``;
``--resume`` keeps those of a
stopped run. ``--rerender DIR`` writes DIR's report.md, fits.csv and figure
again from its report.json, without fitting.

The measured part: every FRF of ``freqid_casadi.systems.measured_sets()`` (shipped in
``freqid_casadi/datasets``) fitted with ``n_sections=range(1, max_sections + 1)``, its
section at the end of report.md and under ``"measured"`` in report.json. It runs with the
full corpus (not with ``--quick`` unless ``--measured``; ``--no-measured`` skips it);
``--measured-only`` runs it alone (default ``--out results/corpus-measured``);
``--measured-sets`` and ``--measured-max-sections`` choose a quicker subset.
"""

import argparse
import os
import shlex
import sys
import time

from freqid_casadi.errors import FreqidError
from freqid_casadi.studies.corpus import FULL_CASES, QUICK_CASES
from freqid_casadi.studies.corpus_report import rerender_corpus_report, write_corpus_report


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="60 cases of at most 400 points")
    ap.add_argument("--n", type=int, default=None, help=f"cases (default {FULL_CASES})")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-points", type=int, default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-auto", action="store_true", help="skip the n_sections=auto fits")
    ap.add_argument("--out", default=None)
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--resume", action="store_true",
                    help="keep the fits of a stopped run (OUT.checkpoint.jsonl) and run the rest")
    part = ap.add_mutually_exclusive_group()
    part.add_argument("--measured", action="store_true",
                      help="also fit the shipped measured FRFs (the default without --quick)")
    part.add_argument("--no-measured", action="store_true",
                      help="skip the measured FRFs")
    part.add_argument("--measured-only", action="store_true",
                      help="fit only the shipped measured FRFs")
    ap.add_argument("--measured-sets", metavar="A,B", default=None,
                    help="only these measured sets (names of "
                         "freqid_casadi.systems.measured_sets())")
    ap.add_argument("--measured-max-sections", type=int, default=None, metavar="K",
                    help="cap the measured sets' orders at K (a quicker run)")
    ap.add_argument("--rerender", metavar="DIR",
                    help="write DIR's report.md, fits.csv and figure again from its "
                         "report.json (no fits)")
    args = ap.parse_args(argv)
    if args.rerender:
        rerender_corpus_report(args.rerender)
        print(f"report: {os.path.join(args.rerender, 'report.md')}")
        return 0
    n = args.n or (QUICK_CASES if args.quick else FULL_CASES)
    max_points = args.max_points or (400 if args.quick else 5000)
    out = args.out or os.path.join("results", "corpus-measured" if args.measured_only else
                                   "corpus-quick" if args.quick else "corpus")
    measured = args.measured or not (args.quick or args.no_measured)
    command = " ".join(["python scripts/corpus.py"] + [shlex.quote(a) for a in argv])
    checkpoint = out.rstrip("/\\") + ".checkpoint.jsonl"
    if not args.resume and os.path.exists(checkpoint):
        os.remove(checkpoint)
    t0 = time.perf_counter()

    def progress(done, total, rec):
        eta = (time.perf_counter() - t0) / done * (total - done)
        print(f"[{done}/{total}] {rec.case} ({rec.config}): {rec.n_points} points, "
              f"{rec.n_sections} sections, RMS {rec.rms:.3g} (noise {rec.noise:.3g}), "
              f"{rec.status}, {rec.wall_time:.1f} s{' ' + rec.error if rec.error else ''}; "
              f"eta {eta / 60:.1f} min", file=sys.stderr, flush=True)

    def measured_progress(done, total, rec):
        print(f"[measured {done}/{total}] {rec.name}: {rec.n_points} points, "
              f"{rec.n_sections} sections ({rec.order_reason}), RMS {rec.rms:.3g} (noise "
              f"estimate {rec.noise:.3g}), {rec.status}, {rec.wall_time:.1f} s"
              f"{' ' + rec.error if rec.error else ''}", file=sys.stderr, flush=True)

    try:
        write_corpus_report(out, command=command, n=n, seed=args.seed, max_points=max_points,
                            workers=args.workers, auto=not args.no_auto, force=args.force,
                            progress=progress, checkpoint=checkpoint, measured=measured,
                            measured_only=args.measured_only,
                            measured_progress=measured_progress,
                            measured_names=args.measured_sets.split(",")
                            if args.measured_sets else None,
                            measured_max_sections=args.measured_max_sections)
    except (FreqidError, OSError) as exc:
        sys.stderr.write(f"error: {' '.join(str(exc).split())}\n")
        return 2
    if os.path.exists(checkpoint):
        os.remove(checkpoint)
    print(f"report: {os.path.join(out, 'report.md')} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

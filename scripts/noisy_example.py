"""Example A on noisy data: error against the clean system at and between the samples.

Usage::

    python scripts/noisy_example.py [--sections 17] [--out results/noisy] [--force]

Runs the study :mod:`freqid_casadi.studies.noisy` and writes its report folder
(:func:`freqid_casadi.studies.noisy_report.write_noisy_report`): ``report.md`` (first line:
this command), ``report.json`` (every number), ``clean_error.png`` and ``weights.png``.
"""

import argparse
import os
import shlex
import sys

from freqid_casadi.errors import FreqidError
from freqid_casadi.report.formatting import number
from freqid_casadi.studies.noisy_report import write_noisy_report


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", type=int, default=17)
    ap.add_argument("--out", default=os.path.join("results", "noisy"))
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    command = " ".join(["python scripts/noisy_example.py"] + [shlex.quote(a) for a in argv])
    try:
        s = write_noisy_report(args.out, command=command, n_sections=args.sections,
                               force=args.force)
    except (FreqidError, OSError) as exc:
        sys.stderr.write(f"error: {' '.join(str(exc).split())}\n")
        return 2
    for key in ("clean_before", "clean_after"):
        c = s["noisy"][key]
        print(f"{key}: samples max {number(c['samples']['max'])} RMS "
              f"{number(c['samples']['rms'])}; dense max {number(c['dense']['max'])} RMS "
              f"{number(c['dense']['rms'])}")
    print(s["weights_effect"])
    return 0


if __name__ == "__main__":
    sys.exit(main())

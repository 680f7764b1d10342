"""Same numbers before and after a speed change: the reference fits run on two code trees
in one run, side by side (issue 30).

Usage::

    python scripts/speed_check.py [--base REV] [--repeat N] [--out results/speed_check.md]

Exports ``REV`` (default ``HEAD~1``, the commit before the last) with ``git archive`` into
a temporary folder and runs the reference fits there and in this tree, each in a fresh
interpreter (``PYTHONPATH`` set to the tree): examples A, B and C with
``start="sequential"`` and ``start="rational"``, B with the minimax polish
(``objective="minimax"``), the measured actuator at 2 sections (both starts) and 3
sections (rational), and the default fit (``start="best"``, the automatic integrator and
gain sign) of the actuator and of the corpus's measured sets at one order each. A fit
counts as unchanged when its max and RMS relative errors agree to ``RTOL`` (relative) or
both lie below ``FLOOR`` (machine-precision fits, where the last digits are rounding),
and its delay to ``RTOL`` relative to the delay bound's scale (1e-3 s); the table also
says whether the model is the same bit for bit (the SHA-256 of ``model.to_dict()``). With
``--repeat N`` the two trees run N times each, alternately, and each fit's CPU time is
its least over the runs (the machine's load moves between runs). Writes a Markdown table
(first line: this command) and a JSON file beside it.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

RTOL = 1e-6
FLOOR = 1e-12
DELAY_ATOL = 1e-9          # s: RTOL of the 1e-3 s scale of the examples' delays

_RUN = r"""
import hashlib, json, sys, time, warnings
import numpy as np
import freqid_casadi as fc
from freqid_casadi.systems.examples import EXAMPLES
from freqid_casadi.core.data import FrequencyData
warnings.simplefilter("ignore")
rows = []
def add(name, data, **kw):
    t0, c0 = time.perf_counter(), time.process_time()
    r = fc.fit(data, **kw)
    model = json.dumps(r.model.to_dict(), sort_keys=True, default=str).encode()
    rows.append(dict(name=name, cpu=time.process_time() - c0,
                     model_sha256=hashlib.sha256(model).hexdigest(),
                     max_rel_error=float(r.max_rel_error),
                     rms_rel_error=float(r.rms_rel_error), delay=float(r.model.delay),
                     nit=int(r.nit), success=bool(r.success),
                     wall_time=time.perf_counter() - t0))
for ex in "ABC":
    e = EXAMPLES[ex]
    for start in ("sequential", "rational"):
        add(f"{ex} {start}", e.data(), start=start, **e.structure())
e = EXAMPLES["B"]
add("B minimax", e.data(), objective="minimax", **e.structure())
from freqid_casadi.studies.measured import actuator_frf
est = actuator_frf()
act = FrequencyData(est.data.omega, est.data.response, "actuator", unit=est.data.unit)
add("actuator 2 sequential", act, n_sections=2, delay=True, start="sequential")
add("actuator 2 rational", act, n_sections=2, delay=True, start="rational")
add("actuator 3 rational", act, n_sections=3, delay=True, start="rational")
# the default pipeline (rational start, sequential loop when needed, integrator and gain
# sign chosen from both signs' rational starts) as a user runs it
add("actuator 2 default", act, n_sections=2, delay=True)
add("robot arm 3 default", fc.experiment.robot_arm().data, n_sections=3, delay=True)
for name, n in (("resonator_36mm_s21", 2), ("tx190_s21", 3), ("ring_slot_s11", 2),
                ("impact_1", 3)):
    add(f"{name} {n} default", fc.systems.measured(name), n_sections=n, delay=True)
print(json.dumps(rows))
"""


def run_tree(path):
    """The reference fits' rows (list of dict) with ``PYTHONPATH=path``."""
    env = dict(os.environ, PYTHONPATH=path)
    out = subprocess.run([sys.executable, "-c", _RUN], capture_output=True, text=True,
                         env=env, cwd=path, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _least(runs):
    """The rows of the first run with each fit's CPU seconds the least over ``runs``
    (a list of ``(wall, rows)``), and the least wall time."""
    rows = [dict(r) for r in runs[0][1]]
    for i, row in enumerate(rows):
        row["cpu"] = min(rs[i]["cpu"] for _, rs in runs)
    return rows, min(w for w, _ in runs)


def same(a, b):
    """True when two rows agree to the stated tolerances."""
    def close(x, y):
        return (x <= FLOOR and y <= FLOOR) or abs(x - y) <= RTOL * max(abs(x), abs(y))
    return (close(a["max_rel_error"], b["max_rel_error"])
            and close(a["rms_rel_error"], b["rms_rel_error"])
            and abs(a["delay"] - b["delay"]) <= DELAY_ATOL)


def _computed_on():
    """The machine line of the report (both trees ran here, in fresh interpreters)."""
    from freqid_casadi.report.environment import computed_on, environment

    return computed_on(environment())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="HEAD~1")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--out", default=os.path.join("results", "speed_check.md"))
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    runs = {"base": [], "now": []}
    with tempfile.TemporaryDirectory() as tmp:
        arc = subprocess.run(["git", "-C", here, "archive", args.base], capture_output=True,
                             check=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=arc, check=True)
        for i in range(args.repeat):
            for key, path in (("base", tmp), ("now", here)):
                t0 = time.perf_counter()
                rows = run_tree(path)
                runs[key].append((time.perf_counter() - t0, rows))
                print(f"  {key} run {i + 1}: {runs[key][-1][0]:.1f} s", file=sys.stderr)
    base, t_base = _least(runs["base"])
    now, t_now = _least(runs["now"])
    rev = subprocess.run(["git", "-C", here, "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True).stdout.strip()
    # the tree measured is HEAD's unless code changed (not the reports this writes)
    changed = subprocess.run(["git", "-C", here, "status", "--porcelain", "--", ".",
                              ":(exclude)results"], capture_output=True, text=True).stdout
    rev += "-dirty" if changed.strip() else ""
    command = f"python scripts/speed_check.py --base {args.base}" + (
        f" --repeat {args.repeat}" if args.repeat > 1 else "") + (
        "" if args.out == os.path.join("results", "speed_check.md") else f" --out {args.out}")
    runs_text = "one run" if args.repeat == 1 else f"{args.repeat} runs of each, alternately"
    lines = [f"<!-- generated by: {command} -->", "",
             f"# Same numbers: {args.base} against {rev} ({runs_text})", "",
             f"Unchanged: max and RMS relative error to {RTOL:g} relative (or both below "
             f"{FLOOR:g}), delay to {DELAY_ATOL:g} s; `bits`: the same model to the last bit. "
             f"Wall time of all fits: {t_base:.1f} s -> {t_now:.1f} s (fresh interpreters, "
             "least over the runs; 2-core shared machine, times noisy: the table gives each "
             "fit's CPU seconds, least over the runs).", "", _computed_on(), "",
             "| fit | max rel. error before | after | RMS before | after | delay before (s) "
             "| after | iterations | CPU before (s) | after | same | bits |",
             "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---|---|"]
    ok_all = True
    cpu = [0.0, 0.0]
    for a, b in zip(base, now):
        cpu[0] += a["cpu"]
        cpu[1] += b["cpu"]
        ok = same(a, b)
        ok_all &= ok
        lines.append(f"| {a['name']} | {a['max_rel_error']:.10g} | {b['max_rel_error']:.10g} | "
                     f"{a['rms_rel_error']:.6g} | {b['rms_rel_error']:.6g} | {a['delay']:.9g} | "
                     f"{b['delay']:.9g} | {a['nit']} -> {b['nit']} | {a['cpu']:.2f} | "
                     f"{b['cpu']:.2f} | {'yes' if ok else 'NO'} | "
                     f"{'yes' if a['model_sha256'] == b['model_sha256'] else 'no'} |")
    bits = sum(a["model_sha256"] == b["model_sha256"] for a, b in zip(base, now))
    lines += ["", f"All unchanged: **{ok_all}**; the same model to the last bit in {bits} of "
              f"{len(base)}. CPU seconds of all fits: {cpu[0]:.1f} -> {cpu[1]:.1f} "
              f"({cpu[1] / cpu[0]:.2f} times)."]
    text = "\n".join(lines) + "\n"
    print(text)
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    with open(args.out, "w") as fh:
        fh.write(text)
    with open(os.path.splitext(args.out)[0] + ".json", "w") as fh:
        json.dump({"base": args.base, "head": rev, "repeat": args.repeat, "rows_base": base,
                   "rows_head": now, "unchanged": ok_all, "wall_time": [t_base, t_now],
                   "runs": {k: [rows for _, rows in v] for k, v in runs.items()}},
                  fh, indent=1)
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())

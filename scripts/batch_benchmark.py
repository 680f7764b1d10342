"""Batch benchmark: ``freqid batch`` on 128 generated datasets, --jobs 2 against --jobs 1
(issue 8.5).

Usage::

    python scripts/batch_benchmark.py [--out results/batch] [--n-datasets 128]

128 datasets, not 32: since the stage derivatives became ~4x faster, one four-section fit
takes ~0.25 s, and 32 of them (8 s) were dominated by the workers' start-up (imports,
~2 s) rather than by the parallel fitting the benchmark is about (measured: 1.24x at 32,
1.84x at 128 on the same machine).

Generates ``n`` datasets (seeded): random stable, minimum-phase four-section models with
an integrator and a delay, 400 points from 0.1 to 300 rad/s, written as CSV to a temporary
folder. Runs ``freqid batch DIR --out OUT --sections 4 --integrator`` once with ``--jobs 1``
and once with ``--jobs 2``, each in a fresh interpreter (the wall time includes start-up,
as a user sees it), checks that both wrote byte-identical model files, and prints the
speed-up ratio, and the CPU seconds of each run (user + system of the run and its
workers: equal CPU seconds with a speed-up below 2 mean the cores were shared with other
work, not parallel overhead). Writes ``<out>/benchmark.json`` and ``<out>/benchmark.md``
(first line: this command). Target: speed-up >= 1.6 on the 2-core machine. A control (one vs two
concurrent busy-loop processes, before and after) measures the speed-up the machine
offered at the time, since the machine may be shared.

The ``batch`` command is registered here if ``cli.py`` does not have it yet.
"""

import argparse
import collections
import csv
import json
import os
import platform
import resource
import shlex
import subprocess
import sys
import tempfile
import time

import numpy as np

import freqid_casadi as fc
from freqid_casadi.report.environment import computed_on, environment
from freqid_casadi.report.folder import atomic_write_text, generated_by_line, markdown_table

SEED = 8
N_POINTS = 400
N_SECTIONS = 4

_BUSY = "x = 0\nfor i in range(15_000_000):\n    x += i\n"

_RUN = """
import sys
from freqid_casadi.cli import app as cli
from freqid_casadi.cli import batch as cli_batch
cli.COMMANDS.setdefault("batch", (cli_batch.add_cli, cli_batch.run_cli))
sys.exit(cli.main(sys.argv[1:]))
"""


def make_datasets(folder, n):
    """Write n seeded random four-section datasets as CSV; returns their paths."""
    rng = np.random.default_rng(SEED)
    omega = np.logspace(-1, np.log10(300.0), N_POINTS)
    paths = []
    for k in range(n):
        beta = [rng.uniform(0.0, 0.01), rng.uniform(0.5, 5.0)]
        for wc in (rng.uniform(0.5, 2), rng.uniform(4, 10), rng.uniform(20, 50),
                   rng.uniform(80, 200)):
            beta += [1.0, rng.uniform(0.01, 0.3), wc * rng.uniform(0.6, 0.9),
                     1.0, rng.uniform(0.01, 0.3), wc]
        model = fc.RationalDelayModel(fc.Structure(N_SECTIONS, True, True), beta)
        data = fc.FrequencyData(omega, model.frequency_response(omega), f"set{k:02d}")
        path = os.path.join(folder, f"set{k:02d}.csv")
        fc.save_csv(data, path)
        paths.append(path)
    return paths


def run_batch(folder, out, jobs):
    argv = ["batch", folder, "--out", out, "--sections", str(N_SECTIONS), "--integrator",
            "--jobs", str(jobs)]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _RUN, *argv], capture_output=True,
                          text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    if proc.returncode not in (0, 1):
        raise SystemExit(f"freqid batch --jobs {jobs} failed: {proc.stderr.strip()}")
    return wall, cpu, proc.returncode, proc.stdout.strip().splitlines()[-1]


def control_speedup():
    """Speed-up the machine offers now: a fixed pure-Python loop in one process, then in two
    processes at once (twice the work); ``2 * t1 / t2`` is 2 on two idle cores and less
    when other work shares them."""
    def run(n):
        t0 = time.perf_counter()
        procs = [subprocess.Popen([sys.executable, "-c", _BUSY]) for _ in range(n)]
        for p in procs:
            p.wait()
        return time.perf_counter() - t0

    t1, t2 = run(1), run(2)
    return dict(t1_s=t1, t2_s=t2, speedup=2 * t1 / t2)


def _models(out):
    folder = os.path.join(out, "models")
    return {n: open(os.path.join(folder, n), encoding="utf-8").read()
            for n in sorted(os.listdir(folder))}


def _statuses(out):
    """The ``status`` column of the batch's summary.csv (ok, poor-fit, not-converged or
    error), one per file."""
    with open(os.path.join(out, "summary.csv"), encoding="utf-8", newline="") as fh:
        return [row["status"] for row in csv.DictReader(fh)]


def _readable(folder, names):
    """atomic_write_text leaves the 0600 of its temporary file: give the umask's mode."""
    mask = os.umask(0o022)
    os.umask(mask)
    for name in names:
        os.chmod(os.path.join(folder, name), 0o666 & ~mask)


def _load(values):
    return "-" if values is None else ", ".join(f"{v:.2f}" for v in values)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="results/batch")
    parser.add_argument("--n-datasets", type=int, default=128)
    args = parser.parse_args(argv)
    command = " ".join(["python", "scripts/batch_benchmark.py"]
                       + [shlex.quote(a) for a in (argv or sys.argv[1:])])
    load_before = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    control = [control_speedup()]
    with tempfile.TemporaryDirectory(prefix="freqid-batch-") as tmp:
        data_dir = os.path.join(tmp, "data")
        os.mkdir(data_dir)
        make_datasets(data_dir, args.n_datasets)
        runs = {}
        for jobs in (1, 2):
            out = os.path.join(tmp, f"out{jobs}")
            wall, cpu, code, last = run_batch(data_dir, out, jobs)
            runs[jobs] = dict(wall_s=wall, cpu_s=cpu, exit_code=code, summary=last,
                              statuses=_statuses(out), models=_models(out))
            sys.stderr.write(f"--jobs {jobs}: {wall:.1f} s wall, {cpu:.1f} s CPU ({last})\n")
        identical = runs[1]["models"] == runs[2]["models"]
    control.append(control_speedup())
    achievable = float(np.mean([c["speedup"] for c in control]))
    speedup = runs[1]["wall_s"] / runs[2]["wall_s"]
    # converged as the batch's exit code counts it: status "ok" or "poor-fit"
    n_conv = sum(s in ("ok", "poor-fit") for s in runs[1]["statuses"])
    counts = dict(sorted(collections.Counter(runs[1]["statuses"]).items()))
    payload = dict(
        command=command, n_datasets=args.n_datasets, n_points=N_POINTS,
        n_sections=N_SECTIONS, seed=SEED,
        machine=f"{platform.machine()}, {os.cpu_count()} cores, "
                f"Python {platform.python_version()}",
        environment=environment(), load_average=load_before,
        wall_s_jobs1=runs[1]["wall_s"], wall_s_jobs2=runs[2]["wall_s"], speedup=speedup,
        cpu_s_jobs1=runs[1]["cpu_s"], cpu_s_jobs2=runs[2]["cpu_s"],
        control=control, achievable_speedup=achievable,
        parallel_efficiency=speedup / achievable,
        load_average_after=list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        target_speedup=1.6, meets_target=bool(speedup >= 1.6),
        models_identical=bool(identical), converged=n_conv, statuses=counts,
        per_file_mean_s=runs[1]["wall_s"] / args.n_datasets)
    os.makedirs(args.out, exist_ok=True)
    atomic_write_text(os.path.join(args.out, "benchmark.json"),
                      json.dumps(payload, indent=1) + "\n")
    table = markdown_table(
        [("--jobs 1", f"{runs[1]['wall_s']:.1f}", f"{runs[1]['cpu_s']:.1f}", "1.00"),
         ("--jobs 2", f"{runs[2]['wall_s']:.1f}", f"{runs[2]['cpu_s']:.1f}",
          f"{speedup:.2f}")],
        ("run", "wall time (s)", "CPU time (s)", "speed-up"), align="lrrr")
    md = "\n".join([
        generated_by_line(command), "", "# Batch benchmark", "",
        f"`freqid batch` on {args.n_datasets} generated datasets ({N_POINTS} points, "
        f"{N_SECTIONS} sections, integrator and delay; seed {SEED}), each run in a fresh "
        f"interpreter. Machine: {payload['machine']}; load average (1, 5, 15 min) before "
        f"the runs {_load(payload['load_average'])}, after "
        f"{_load(payload['load_average_after'])}.", "", computed_on(payload["environment"]),
        "", table, "",
        f"Speed-up {speedup:.2f} (target >= 1.6: "
        f"{'met' if payload['meets_target'] else 'NOT met'}). Model files identical "
        f"between the runs: {'yes' if identical else 'NO'}. Converged (status ok or "
        f"poor-fit): {n_conv}/{args.n_datasets}; statuses: "
        + ", ".join(f"{k} {v}" for k, v in counts.items()) + ".", "",
        f"Control (same machine, same time): a fixed pure-Python loop run once in one "
        f"process and then in two processes at once gives a speed-up of "
        f"{achievable:.2f} (mean of before and after; 2.0 on two idle cores), so the "
        f"batch reached {speedup / achievable:.0%} of what the machine offered. CPU "
        f"seconds {runs[1]['cpu_s']:.1f} (--jobs 1) vs {runs[2]['cpu_s']:.1f} (--jobs 2) "
        "show the parallel overhead (worker start-up, imports, pickling).", ""])
    atomic_write_text(os.path.join(args.out, "benchmark.md"), md)
    _readable(args.out, ("benchmark.json", "benchmark.md"))
    print(f"jobs 1: {runs[1]['wall_s']:.1f} s, jobs 2: {runs[2]['wall_s']:.1f} s, "
          f"speed-up {speedup:.2f}x (target 1.6; the machine offered {achievable:.2f}x), "
          f"CPU {runs[1]['cpu_s']:.1f} s vs {runs[2]['cpu_s']:.1f} s, "
          f"models identical: {identical}")
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())

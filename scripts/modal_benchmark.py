"""Benchmark of fit_shared: 16 channels x 1000 points x 10 shared modes, and the time per
IPOPT iteration at 8, 16 and 32 channels measured in one run (it should grow linearly).

Data: Moheimani's simply-supported beam (SPEC §4; freqid_casadi.systems.moheimani_modes),
truncated to its first 10 modes, modal damping 0.01, actuator at r1 = 0.075 m and one sensor
per channel spread over the beam, 1000 log-spaced points from 5 to 2000 rad/s, 0.2 %
complex Gaussian noise (seed 16). The collocated channel is fitted minimum phase, the others
with zeros="free". Also draws an example stabilization diagram with the selected modes'
shapes and their MAC against the analytic ones, and fits a roving-hammer modal test of a
free-free beam (issue 31): 9 hammer points, one accelerometer, accelerance, 4 modes damped
0.05 % .. 0.013 %, 51 200 points up to 1000 Hz (47 872 in 65..1000 Hz), 1 % noise (seed 31),
shared poles, shapes
and MAC against the analytic shapes. With ``--measured DIR`` (the folder of ASCII00001 ..
ASCII00009 of alxhslm/ModeLAB's Example/SignalCalc, not shipped: GPL-3) the same fit on the
measured beam, against its published frequencies.

Writes results/modal/report.md (first line: the command), benchmark.json,
stabilization.png, stabilization.csv, modes.md, shapes.csv, modal_test_shapes.csv,
modal_test_shape_<k>.png.

    python scripts/modal_benchmark.py [--quick] [--measured DIR]
"""

import argparse
import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import freqid_casadi as fc  # noqa: E402
from freqid_casadi.report.environment import computed_on_lines, environment  # noqa: E402
from freqid_casadi.report.formatting import generated_by_line  # noqa: E402
from freqid_casadi.core.modes import modes_markdown  # noqa: E402
from freqid_casadi.modal.survey import stabilization, stabilization_csv  # noqa: E402
from freqid_casadi.modal.shared import fit_shared  # noqa: E402
from freqid_casadi.systems import moheimani_modes  # noqa: E402

OUT = os.path.join(ROOT, "results", "modal")
N_MODES, ZETA, R1 = 10, 0.01, 0.075


def beam_channels(n_channels, n_points=1000, noise=2e-3, seed=16):
    """FrequencyData per sensor: 10-mode beam, sensors at r1 and spread over (0, L)."""
    rng = np.random.default_rng(seed)
    w = np.geomspace(5.0, 2000.0, n_points)
    s = 1j * w[:, None]
    positions = [R1] + list(np.linspace(0.11, 1.27, n_channels - 1))
    out = []
    for r2 in positions:
        wi, fi = moheimani_modes(N_MODES, r1=R1, r2=float(r2))
        g = np.sum(fi / (s * s + 2 * ZETA * wi * s + wi * wi), axis=1)
        g = g * (1 + noise * (rng.normal(size=w.size) + 1j * rng.normal(size=w.size))
                 / np.sqrt(2))
        out.append(fc.FrequencyData(w, g, f"r2={r2:.3f}"))
    return out


def zeros_of(n):
    return ["minimum-phase"] + ["free"] * (n - 1)


def timed_fit(n_channels, repeats=3):
    """Fit ``repeats`` times (deterministic: same result); the fastest wall time and the
    fastest time per IPOPT iteration of the polish stage, and the accuracy."""
    datas = beam_channels(n_channels)
    walls, per_it, cpu_it = [], [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fit_shared(datas, N_MODES, delay=False, zeros=zeros_of(n_channels),
                         start="rational")
        walls.append(time.perf_counter() - t0)
        per_it.append(res.stages[-1].t_solve / max(res.stages[-1].nit, 1))
        cpu_it.append(res.stages[-1].cpu_solve / max(res.stages[-1].nit, 1))
    polish = res.stages[-1]
    wi, _ = moheimani_modes(N_MODES)
    found = np.array([m.omega_n for m in res.modes])
    freq_err = [float(np.min(np.abs(found - w)) / w) for w in wi]
    zeta_err = [float(abs(res.modes[int(np.argmin(np.abs(found - w)))].zeta - ZETA) / ZETA)
                for w in wi]
    return {"channels": n_channels, "wall_time": min(walls), "wall_times": walls,
            "nit": polish.nit, "t_per_iteration": min(per_it), "t_per_iteration_all": per_it,
            "cpu_per_iteration": min(cpu_it),
            "status": str(res.status), "message": res.message,
            "solver_status": polish.solver_status, "success": res.success,
            "n_modes": len(res.modes),
            "max_rel_error_worst": float(np.max(res.max_rel_errors)),
            "rms_rel_error_worst": float(np.max(res.rms_rel_errors)),
            "max_freq_error": max(freq_err), "max_zeta_error": max(zeta_err),
            "vector_fitting_time": res.stages[0].wall_time}


def eval_time(n_channels, repeats=20):
    """CPU seconds per evaluation of cost+gradient+Hessian (median of ``repeats``)."""
    from freqid_casadi.modal._nlp import SharedProblem
    from freqid_casadi._threads import single_threaded_blas

    datas = beam_channels(n_channels)
    phi = np.array([d.response for d in datas])
    c, m = phi.shape
    wr = moheimani_modes(N_MODES)[0]
    prob = SharedProblem(datas[0].omega, phi, np.ones((c, m)), np.abs(phi[:, 0]), wr, False,
                         False, np.array([z == "free" for z in zeros_of(c)]), 1.0)
    z = prob.join(np.tile([1.0, 0.02], (N_MODES, 1)), np.ones(c), np.zeros(c),
                  np.tile([1.0, 0.02], (c, N_MODES, 1)))
    times = []
    with single_threaded_blas():
        for k in range(repeats):
            z[0] += 1e-9                  # defeat the cache: a new point every time
            t0 = time.process_time()
            prob.gradient(z)
            prob.hessian_values(z)
            times.append(time.process_time() - t0)
    return float(np.median(times))


FREE_FREE_BL = (4.7300407, 7.8532046, 10.9956078, 14.1371655)     # beta_k L, free-free
HAMMER = (0.1, 0.25, 0.375, 0.5, 0.65, 0.8, 0.925, 1.05, 1.2)     # m, as ModeLAB's test
PUBLISHED_HZ = (111.99, 306.86, 596.37, 974.14)                    # ModeLAB's modeshapes.png


def free_free_shapes(x, length=1.3):
    """Free-free beam bending shapes (4, len(x)), unnormalised."""
    x = np.asarray(x, float)
    out = []
    for bl in FREE_FREE_BL:
        k = bl / length
        sig = (np.cosh(bl) - np.cos(bl)) / (np.sinh(bl) - np.sin(bl))
        out.append(np.cosh(k * x) + np.cos(k * x) - sig * (np.sinh(k * x) + np.sin(k * x)))
    return np.array(out)


def roving_hammer_test(n_points=51200, noise=0.01, seed=31):
    """9 accelerances (m/s^2/N) of a free-free beam hit at HAMMER, sensor at 0.5 m: 4 modes
    at the measured beam's frequencies, damping 0.05 % .. 0.013 %, rigid-body mass line."""
    f_hz, zeta = np.array(PUBLISHED_HZ), np.array([5e-4, 3e-4, 2e-4, 1.3e-4])
    w = 2 * np.pi * np.linspace(1000.0 / n_points, 1000.0, n_points)
    s = 1j * w
    phi, sensor = free_free_shapes(HAMMER), free_free_shapes([0.5])[:, 0]
    rng = np.random.default_rng(seed)
    out = []
    for c, x in enumerate(HAMMER):
        wk = 2 * np.pi * f_hz
        g = sum(phi[k, c] * sensor[k] * s * s / (s * s + 2 * zeta[k] * wk[k] * s + wk[k] ** 2)
                for k in range(4))
        g = g + 1.0 + 12 * (x - 0.65) * (0.5 - 0.65)          # rigid body: a constant
        g = g * (1 + noise * (rng.normal(size=w.size) + 1j * rng.normal(size=w.size))
                 / np.sqrt(2))
        out.append(fc.FrequencyData(w, g, f"x={x:g}"))
    return out, phi


def _band(datas, lo_hz=65.0):
    return [fc.FrequencyData(d.omega[d.omega >= 2 * np.pi * lo_hz],
                             d.response[d.omega >= 2 * np.pi * lo_hz], d.name) for d in datas]


def modal_test(datas, truth_shapes, truth_hz, label):
    """fit_shared at 4 sections (delay none, zeros free), each channel's own fit at 4
    sections, shapes by LSFD and their MAC against ``truth_shapes`` (or None)."""
    import warnings

    t0, c0 = time.perf_counter(), time.process_time()
    res = fit_shared(datas, 4, delay=False, zeros="free")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        own = [float(fit_shared([d], 4, delay=False, zeros="free").rms_rel_errors[0])
               for d in datas]
    sh = res.mode_shapes(coordinates=HAMMER)
    mac = None if truth_shapes is None else fc.mac(sh, truth_shapes)
    f = sh.frequency_hz
    return {"label": label, "channels": len(datas), "points": int(datas[0].n_points),
            "wall_time": wall, "cpu_time": cpu, "success": res.success,
            "status": str(res.status), "message": res.message, "nit": res.nit,
            "frequency_hz": f.tolist(), "zeta": sh.zeta.tolist(),
            "frequency_error_hz": [float(np.min(np.abs(f - t))) for t in truth_hz],
            "rms": res.rms_rel_errors.tolist(), "own_rms": own,
            "rms_ratio": (res.rms_rel_errors / np.array(own)).tolist(),
            "mpc": sh.mpc.tolist(), "mpd_deg": sh.mpd_deg.tolist(),
            "mac_diag": None if mac is None else np.diag(mac).tolist(),
            "shapes": sh.aligned.real.tolist()}, sh


def read_signalcalc(folder):
    """The 9 FRFs of ModeLAB's example (SignalCalc ASCII, Latin-1, 9-line preamble): a
    small reader of this layout only (freqid_casadi.load reads such exports since issue
    31's io half)."""
    datas = []
    for k in range(1, 10):
        path = os.path.join(folder, f"ASCII{k:05d}", f"Hxysv{k:05d}.txt")
        rows = []
        with open(path, encoding="latin-1") as fh:
            for line in fh:
                parts = line.split()
                if len(parts) == 3:
                    try:
                        rows.append([float(v) for v in parts])
                    except ValueError:
                        pass
        a = np.array(rows)
        a = a[(a[:, 0] >= 65.0) & (a[:, 0] <= 1000.0)]
        datas.append(fc.FrequencyData(2 * np.pi * a[:, 0], a[:, 1] + 1j * a[:, 2],
                                      f"H{k}"))
    return datas


def write_shapes(sh, prefix):
    from freqid_casadi.core.modes import shapes_csv
    from freqid_casadi.plots import save_figure
    from freqid_casadi.plots.modal import mode_shape_figure

    with open(os.path.join(OUT, f"{prefix}shapes.csv"), "w", encoding="utf-8") as fh:
        fh.write(shapes_csv(sh))
    for k in range(len(sh)):
        save_figure(mode_shape_figure(sh, k), os.path.join(OUT, f"{prefix}shape_{k + 1}.png"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="skip the stabilization example and the modal test")
    ap.add_argument("--measured", metavar="DIR",
                    help="also fit ModeLAB's measured beam (its Example/SignalCalc folder)")
    ap.add_argument("--out", metavar="DIR",
                    help="folder to write (default results/modal, the full run's; a --quick "
                         "run needs a folder of its own)")
    args = ap.parse_args()
    global OUT
    if args.out:
        OUT = os.path.abspath(args.out)
    elif args.quick:
        ap.error("--quick writes part of the report only, which would replace the full run's "
                 "in results/modal: pass --out DIR")
    command = "python scripts/modal_benchmark.py" + (" --quick" if args.quick else "") + \
        (" --measured DIR" if args.measured else "") + (f" --out {args.out}" if args.out else "")
    os.makedirs(OUT, exist_ok=True)
    runs = [timed_fit(c) for c in (8, 16, 32)]
    evals = {c: eval_time(c) for c in (8, 16, 32)}
    for r in runs:
        print(f"{r['channels']:3d} channels: {r['wall_time']:.2f} s, {r['nit']} it, "
              f"{1e3 * r['t_per_iteration']:.1f} ms/it (CPU {1e3 * r['cpu_per_iteration']:.1f}"
              f" ms/it), worst max rel. error "
              f"{r['max_rel_error_worst']:.3g}, freq. error {r['max_freq_error']:.2e}")
    tpi = {r["channels"]: r["t_per_iteration"] for r in runs}
    cpi = {r["channels"]: r["cpu_per_iteration"] for r in runs}
    ratios = {"cpu_it_16/cpu_it_8": cpi[16] / cpi[8], "cpu_it_32/cpu_it_16": cpi[32] / cpi[16],
              "t_it_16/t_it_8": tpi[16] / tpi[8], "t_it_32/t_it_16": tpi[32] / tpi[16],
              "t_eval_16/t_eval_8": evals[16] / evals[8],
              "t_eval_32/t_eval_16": evals[32] / evals[16]}
    print("ratios (linear growth = 2.0):", {k: round(v, 2) for k, v in ratios.items()})
    result = {"command": command, "runs": runs, "eval_time": evals, "ratios": ratios,
              "target": "16 channels x 1000 points x 10 modes in <= 30 s",
              "environment": environment()}
    if not args.quick:
        result["stabilization"] = stabilization_example()
        datas, phi = roving_hammer_test()
        result["modal_test"], sh = modal_test(_band(datas), phi, PUBLISHED_HZ,
                                              "synthetic free-free beam")
        write_shapes(sh, "modal_test_")
        print("modal test:", {k: result["modal_test"][k] for k in
                              ("wall_time", "cpu_time", "frequency_error_hz", "mac_diag")})
    if args.measured:
        result["measured"] = modal_test(read_signalcalc(args.measured), None, PUBLISHED_HZ,
                                        "ModeLAB's measured beam")[0]
    with open(os.path.join(OUT, "benchmark.json"), "w", encoding="utf-8") as fh:
        json.dump(result, fh, indent=1)
    with open(os.path.join(OUT, "report.md"), "w", encoding="utf-8") as fh:
        fh.write(render(result))
    print(f"wrote {OUT}")


def stabilization_example():
    """Stabilization diagram of 6 channels (500 points) at orders 12..32."""
    from freqid_casadi.plots import save_figure
    from freqid_casadi.plots.modal import stabilization_diagram

    datas = [fc.FrequencyData(d.omega[::2], d.response[::2], d.name)
             for d in beam_channels(6)]
    t0 = time.perf_counter()
    res = stabilization(datas, range(12, 33, 2), delay=False, zeros=zeros_of(6),
                        method=fc.IpoptOptions(max_iter=100, final_max_iter=200))
    wall = time.perf_counter() - t0
    save_figure(stabilization_diagram(res), os.path.join(OUT, "stabilization.png"))
    with open(os.path.join(OUT, "stabilization.csv"), "w", encoding="utf-8") as fh:
        fh.write(stabilization_csv(res))
    names = [d.name for d in datas]
    with open(os.path.join(OUT, "modes.md"), "w", encoding="utf-8") as fh:
        fh.write("<!-- generated by: python scripts/modal_benchmark.py -->\n\n"
                 + modes_markdown(res.modes, names))
    wi, _ = moheimani_modes(N_MODES)
    found = np.array([m.omega_n for m in res.modes])
    err = [float(np.min(np.abs(wi - w)) / w) for w in found]
    # the selected modes' shapes (LSFD at the polished fit's poles) against the analytic ones
    top = res.polished
    sh = top.mode_shapes(coordinates=[0.075] + list(np.linspace(0.11, 1.27, 5)))
    keep = [int(np.argmin([abs(m.omega_n - t.omega_n) for m in top.modes])) for t in res.modes]
    positions = [R1] + list(np.linspace(0.11, 1.27, 5))
    truth = np.array([moheimani_modes(N_MODES, r1=R1, r2=float(r))[1] for r in positions]).T
    mac = fc.mac(sh.aligned[keep], truth)
    best = [float(np.max(row)) for row in mac]
    from freqid_casadi.core.modes import shapes_csv
    with open(os.path.join(OUT, "shapes.csv"), "w", encoding="utf-8") as fh:
        fh.write(shapes_csv(sh))
    return {"orders": list(res.orders), "wall_time": wall, "n_selected": len(res.modes),
            "selection_note": res.selection_note, "mac_best": best,
            "mpc": [float(sh.mpc[k]) for k in keep],
            "selected_hz": [m.frequency_hz for m in res.modes],
            "analytic_hz": list(wi / (2 * np.pi)),
            "n_analytic_found": int(sum(np.min(np.abs(found - w)) / w < 0.005 for w in wi))
            if found.size else 0,
            "max_freq_error_selected": max(err) if err else None}


def render(r):
    lines = [generated_by_line(r['command']), "", "# fit_shared benchmark (issue 16)", "",
             "Moheimani's beam truncated to 10 modes (damping 0.01), one actuator at 0.075 m, "
             "sensors spread over the beam, 1000 log points 5..2000 rad/s, 0.2 % noise; "
             "10 shared sections, delay none, collocated channel minimum phase, the others "
             "zeros='free'. 2-core machine shared with other jobs: timings are noisy.", "",
             *computed_on_lines(r.get("environment")),
             "Wall time and time per iteration: fastest of 3 runs in the same process.", "",
             "| channels | wall time (s) | IPOPT iterations (polish) | ms / iteration | "
             "CPU ms / iteration | worst max rel. error | worst freq. error | "
             "worst damping error | status |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for x in r["runs"]:
        lines.append(f"| {x['channels']} | {x['wall_time']:.2f} | {x['nit']} | "
                     f"{1e3 * x['t_per_iteration']:.1f} | {1e3 * x['cpu_per_iteration']:.1f} | "
                     f"{x['max_rel_error_worst']:.3g} | "
                     f"{x['max_freq_error']:.2e} | {x['max_zeta_error']:.2e} | "
                     f"{x['status']} |")
    lines += ["", "Messages (SharedFitResult.message): " + "; ".join(
        f"{x['channels']} channels: {x['message']}" for x in r["runs"]) + ".", "",
              "CPU time of one cost+gradient+Hessian evaluation (median of 20, one "
              "thread): " + ", ".join(
        f"{c} ch. {1e3 * t:.1f} ms" for c, t in r["eval_time"].items()) + ".", "",
        "Ratios (linear growth in the number of channels gives 2.0; CPU time of this "
        "process is the robust measure on the shared machine, wall time is noisy): " + ", ".join(
        f"{k} = {v:.2f}" for k, v in r["ratios"].items()) + ".", ""]
    if "stabilization" in r:
        s = r["stabilization"]
        lines += ["## Stabilization example", "",
                  f"6 channels, 500 points, orders {s['orders'][0]}..{s['orders'][-1]} step 2 "
                  f"(min_stable 3, tolerances 1 % / 10 %): {s['n_selected']} modes selected "
                  f"in {s['wall_time']:.1f} s; {s['n_analytic_found']} of the 10 analytic "
                  f"modes within 0.5 % of a selected one; worst frequency error of a "
                  f"selected mode against the nearest analytic one "
                  f"{s['max_freq_error_selected']:.2e}. "
                  "![stabilization](stabilization.png) (stabilization.csv, modes.md)", "",
                  "Shapes of the selected modes (LSFD at the top order's poles, shapes.csv): "
                  "MAC against the nearest analytic shape " + ", ".join(
                      f"{v:.4f}" for v in s["mac_best"]) + "; MPC " + ", ".join(
                      f"{v:.4f}" for v in s["mpc"]) + ".", ""]
    for key in ("modal_test", "measured"):
        if key in r:
            lines += _modal_test_lines(r[key])
    return "\n".join(lines)


def _modal_test_lines(m):
    head = ("## Roving-hammer modal test: " + m["label"] + "\n\n" +
            f"{m['channels']} channels x {m['points']} points (65..1000 Hz), 4 shared "
            f"sections, delay none, zeros free: {m['wall_time']:.1f} s wall, "
            f"{m['cpu_time']:.1f} s CPU (this process; the machine is shared), "
            f"{m['nit']} IPOPT iterations; {m['message']}."
            f" Reference frequencies: {', '.join(f'{v:g}' for v in PUBLISHED_HZ)} Hz.")
    lines = [head, "",
             "| mode | f (Hz) | zeta (%) | error vs reference (Hz) | MPC | MPD (deg) | MAC vs "
             "analytic |", "|---:|---:|---:|---:|---:|---:|---:|"]
    for k, f in enumerate(m["frequency_hz"]):
        mac = "" if m["mac_diag"] is None else f"{m['mac_diag'][k]:.4f}"
        err = min(abs(f - t) for t in PUBLISHED_HZ)
        lines.append(f"| {k + 1} | {f:.4f} | {100 * m['zeta'][k]:.4f} | {err:.3f} | "
                     f"{m['mpc'][k]:.4f} | {m['mpd_deg'][k]:.2f} | {mac} |")
    lines += ["", "Each channel's RMS relative error, shared fit / its own fit (fit_shared on "
              "the channel alone, 4 sections): " + ", ".join(
                  f"{a:.3f}/{b:.3f}" for a, b in zip(m["rms"], m["own_rms"])) +
              f" (worst ratio {max(m['rms_ratio']):.3f}).", ""]
    return lines


if __name__ == "__main__":
    main()

"""From measured FRFs of a plant family to an H-infinity controller checked on the data.

Usage::

    python scripts/robust_design.py [--out results/robust] [--members 10] [--seed 29]

A flexible structure with a delay (a collocated modal sum of three modes, 20 ms of
delay) and a family of measured-like variants: stiffness spread +-25 % (mode frequencies
about +-12 %), damping spread +-30 %, 1 % complex noise on every point. The script

1. fits the nominal (``fc.fit`` of the nominal unit's measured FRF, three sections);
2. covers the family (``fc.cover(model, members, pade_order=2)``: one stable,
   minimum-phase weight W(s) above every member's relative error against the rational
   nominal whose delay is a Pade approximation);
3. designs a controller with ``control.mixsyn`` (W1 a performance weight on S, W2 a small
   constant on KS, W3 = W on T), taking the widest performance bandwidth for which the
   synthesis reaches gamma < 1, so that ||W T||_inf < 1;
4. checks robust stability on every member's measured FRF directly: the loop
   L_i(jw) = Phi_i(jw) K(jw) from the data (no fitted model in between), its Nyquist
   winding number, gain, phase and modulus margins; and |W T| < 1 on the data's grid;
5. simulates the step response of every member's own fitted model in the loop;

and writes ``report.md`` (first line: the command), ``report.json`` and the figures.
"""

import argparse
import json
import math
import os
import shlex
import sys
import time

import numpy as np

import freqid_casadi as fc
from freqid_casadi.fitting.far_roots import roots_to_infinity
from freqid_casadi.report.environment import computed_on_lines, environment

WN = np.array([4.0, 15.0, 38.0])       # rad/s: mode frequencies of the nominal unit
ZETA = np.array([0.02, 0.015, 0.01])   # modal dampings
RES = np.array([1.0, 0.35, 0.12])      # modal participation (collocated: all > 0)
DELAY = 0.02                           # s
OMEGA = np.logspace(np.log10(0.05), np.log10(400.0), 500)    # rad/s
NOISE = 0.01                           # relative complex noise per point
STIFFNESS_SPREAD = 0.25                # +-: mode frequencies scale with sqrt(stiffness)
DAMPING_SPREAD = 0.30                  # +-
PADE_ORDER = 2                         # Pade order of the synthesis nominal
SIM_PADE_ORDER = 6                     # Pade order of the step-response simulations
BANDWIDTHS = np.geomspace(0.05, 5.0, 9)    # rad/s: performance bandwidths tried
BISECTIONS = 4                         # then halvings of the last log interval
COVER_TIGHTNESS = 3.0                  # fc.cover: lowest order with median |W|/env <= 3
S_PEAK = 2.0                           # W1: |S| <= 2 at high frequency
S_FLOOR = 1e-3                         # W1: |S| <= 1e-3 at low frequency
KS_WEIGHT = 1e-2                       # W2: the constant weight on K S


def plant(omega, wn, zeta, res, delay):
    """``exp(-h s) sum_k r_k wn_k^2 / (s^2 + 2 zeta_k wn_k s + wn_k^2) / sum(r)`` at jw."""
    s = 1j * np.asarray(omega, float)
    g = sum(r * w * w / (s * s + 2 * z * w * s + w * w) for w, z, r in zip(wn, zeta, res))
    return np.exp(-delay * s) * g / float(np.sum(res))


def family(n_members, seed):
    """The nominal unit's and the members' measured-like FRFs, and their parameters."""
    rng = np.random.default_rng(seed)

    def measured(wn, zeta, name):
        g = plant(OMEGA, wn, zeta, RES, DELAY)
        noise = NOISE / math.sqrt(2) * (rng.standard_normal(g.size)
                                        + 1j * rng.standard_normal(g.size))
        return fc.FrequencyData(OMEGA, g * (1 + noise), name=name)

    nominal = measured(WN, ZETA, "nominal unit")
    members, params = [], []
    for i in range(n_members):
        k = 1 + rng.uniform(-STIFFNESS_SPREAD, STIFFNESS_SPREAD, WN.size)
        z = 1 + rng.uniform(-DAMPING_SPREAD, DAMPING_SPREAD, WN.size)
        wn, zeta = WN * np.sqrt(k), ZETA * z
        members.append(measured(wn, zeta, f"unit {i + 1}"))
        params.append({"omega_n": wn.tolist(), "zeta": zeta.tolist()})
    return nominal, members, params


# ----------------------------------------------------------------------------- design
def performance_weight(ct, bandwidth):
    """W1(s) = (s / S_PEAK + wb) / (s + wb S_FLOOR): |S| below 1/|W1|."""
    return ct.tf([1.0 / S_PEAK, bandwidth], [1.0, bandwidth * S_FLOOR])


def _synthesis(ct, g_nom, w_unc, wb, tried):
    """mixsyn at the performance bandwidth ``wb``; None if slycot finds no solution."""
    w1 = performance_weight(ct, wb)
    try:
        k, _, info = ct.mixsyn(g_nom, w1, ct.tf([KS_WEIGHT], [1.0]), w_unc)
    except Exception as exc:                # slycot: no solution at this bandwidth
        print(f"  mixsyn at wb={wb:.3g}: {type(exc).__name__}", file=sys.stderr)
        tried.append((float(wb), math.nan))
        return None
    gamma = float(info[0])
    print(f"  mixsyn at wb={wb:.3g} rad/s: gamma {gamma:.4f}", file=sys.stderr)
    tried.append((float(wb), gamma))
    return {"K": k, "gamma": gamma, "bandwidth": float(wb), "W1": w1}


def design(ct, g_nom, w_unc):
    """The widest performance bandwidth with mixsyn's gamma < 1: BANDWIDTHS in turn up
    to the first that fails, then BISECTIONS halvings of the log interval."""
    best, fail, tried = None, None, []
    for wb in BANDWIDTHS:
        out = _synthesis(ct, g_nom, w_unc, wb, tried)
        if out is not None and out["gamma"] < 1.0:
            best = out
        else:
            fail = wb
            break
    if best is None:
        raise SystemExit("no bandwidth reaches gamma < 1: the cover is too wide")
    lo = best["bandwidth"]
    for _ in range(BISECTIONS if fail is not None else 0):
        wb = math.sqrt(lo * fail)
        out = _synthesis(ct, g_nom, w_unc, wb, tried)
        if out is not None and out["gamma"] < 1.0:
            best, lo = out, wb
        else:
            fail = wb
    best["tried"] = sorted(tried)
    return best


def response(ct, sys, omega):
    """Complex frequency response of a python-control system, shape (M,)."""
    return np.asarray(ct.frequency_response(sys, omega).complex).reshape(-1)


# ----------------------------------------------------------------------------- checks
def winding_number(one_plus_l):
    """Counter-clockwise turns of ``1 + L`` about 0 as w runs over -inf..inf, from its
    values on 0 <= w <= w_max (conjugate symmetry; the ends must be near the real axis)."""
    phase = np.unwrap(np.angle(one_plus_l))
    return 2.0 * (phase[-1] - phase[0]) / (2.0 * math.pi)


def crossings(x, y, level):
    """The x where the sampled y crosses ``level`` (linear interpolation)."""
    d = y - level
    idx = np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)
    return [x[i] + (x[i + 1] - x[i]) * (-d[i]) / (d[i + 1] - d[i]) for i in idx]


def margins(omega, loop):
    """Gain margin (min 1/|L| at a phase crossover), phase margin, their frequencies, the
    modulus margin min |1 + L| and the delay margin.

    The phase margin is, at each gain crossover, the phase change of either sign that
    puts L on -1 (0..180 deg), the smallest over the crossovers: a loop with several
    crossovers (here the controller's gain above 1 near a mode) can cross |L| = 1 with L
    near +1, where the signed margin 180 + phase (wrapped) would read about -170 deg for
    a point far from -1. Stability itself is the winding number's. The delay margin is
    the smallest, over the crossovers, of the extra lag that reaches -1 (a delay only
    lags) over the crossover's frequency (s)."""
    mag, ph = np.abs(loop), np.unwrap(np.angle(loop))
    gm, w_gm = math.inf, math.nan
    for k in range(-5, 6):                               # phase = -180 deg + k 360
        for w in crossings(np.log(omega), ph, -math.pi + 2 * math.pi * k):
            w = math.exp(w)
            m = float(np.exp(np.interp(np.log(w), np.log(omega), np.log(mag))))
            if 1.0 / m < gm:
                gm, w_gm = 1.0 / m, w
    pm, w_pm, delay_margin = math.inf, math.nan, math.inf
    for w in crossings(np.log(omega), np.log(mag), 0.0):
        w = math.exp(w)
        p = float(np.interp(np.log(w), np.log(omega), ph))
        lag = (p + math.pi) % (2 * math.pi)              # extra lag that reaches -1 (rad)
        margin = math.degrees(min(lag, 2 * math.pi - lag))
        if margin < pm:
            pm, w_pm = margin, w
        delay_margin = min(delay_margin, lag / w)
    if not math.isfinite(delay_margin):
        delay_margin = math.nan
    return {"gain_margin": gm, "gain_margin_db": 20 * math.log10(gm) if gm > 0 else -math.inf,
            "omega_gain_margin": w_gm, "phase_margin_deg": pm, "omega_crossover": w_pm,
            "modulus_margin": float(np.min(np.abs(1 + loop))), "delay_margin": delay_margin}


def check_member(ct, data, k_sys, w_cov, t_nom, n_open_rhp):
    """Robust stability of one member from its measured FRF (module notes, step 4)."""
    k_data = response(ct, k_sys, data.omega)
    loop = data.response * k_data                      # measured plant, exact controller
    # below the first measured frequency the plant is taken flat at its first point (the
    # measured low-frequency plateau); the controller is exact there
    w_low = np.geomspace(data.omega[0] * 1e-4, data.omega[0], 200, endpoint=False)
    low = data.response[0] * response(ct, k_sys, w_low)
    full = np.concatenate([low, loop])
    turns = winding_number(1 + full)
    closed_rhp = n_open_rhp - turns                    # Z = P + N_cw, N_cw = -turns
    wt = np.abs(w_cov.frequency_response(data.omega) * t_nom)
    out = margins(data.omega, loop)
    out.update(name=data.name, winding=float(turns),
               closed_loop_rhp_poles=int(round(closed_rhp)),
               stable=bool(abs(closed_rhp) < 0.25),
               loop_at_omega_max=float(abs(loop[-1])),
               low_end_phase_deg=float(np.degrees(np.angle(1 + full[0]))),
               max_WT_on_grid=float(np.max(wt)))
    return out, loop


def step_metrics(t, y):
    """Final value, overshoot (%) and 2 % settling time of a step response."""
    final = float(np.mean(y[-max(5, y.size // 50):]))
    over = max(0.0, (float(np.max(y)) - final) / abs(final) * 100.0) if final else math.nan
    outside = np.flatnonzero(np.abs(y - final) > 0.02 * abs(final))
    settle = float(t[outside[-1] + 1]) if outside.size and outside[-1] + 1 < t.size else (
        0.0 if not outside.size else math.nan)
    return {"final": final, "overshoot_pct": over, "settling_time": settle}


def step_responses(ct, members, k_sys, progress):
    """Each member's own fitted model (3 sections, delay by Pade) in the loop with K."""
    t = np.linspace(0.0, 30.0, 3001)
    out = []
    for d in members:
        res = fc.fit(d, n_sections=3)
        model = roots_to_infinity(res.model, OMEGA[-1])[0]     # as the nominal's
        g = model.to_control(delay="pade", pade_order=SIM_PADE_ORDER)
        cl = ct.feedback(ct.series(k_sys, g), 1)
        y = np.asarray(ct.step_response(cl, t).outputs).reshape(-1)
        m = step_metrics(t, y)
        m.update(name=d.name, fit_max_rel_error=float(res.max_rel_error),
                 fit_delay=float(res.model.delay),
                 closed_loop_stable=bool(np.all(np.real(ct.poles(cl)) < 0)))
        progress(f"  {d.name}: fit max rel. error {res.max_rel_error:.3g}, step overshoot "
                 f"{m['overshoot_pct']:.1f} %, settling {m['settling_time']:.2f} s")
        out.append((m, t, y))
    return out


# ----------------------------------------------------------------------------- figures
def figures(folder, cov, members, loops, checks, nominal_curves, steps, design_info):
    import matplotlib.pyplot as plt

    w_dense = np.geomspace(OMEGA[0], OMEGA[-1], 2000)
    mag_w = np.abs(cov.frequency_response(w_dense))

    fig, ax = plt.subplots(figsize=(8, 5))
    for i, (w, e) in enumerate(zip(cov.member_omegas, cov.member_errors)):
        ax.loglog(w, e, lw=0.7, alpha=0.7, label="members |G_i/G_R - 1|" if i == 0 else None)
    ax.loglog(cov.omega, cov.envelope, "k", lw=1.2, label="envelope (max over members)")
    ax.loglog(w_dense, mag_w, "r", lw=2.2, label=f"|W| (order {cov.order})")
    if cov.pade_error is not None:
        ax.loglog(cov.omega, np.maximum(cov.pade_error, 1e-12), "c--", lw=1,
                  label=f"Pade error (order {cov.pade_order})")
    ax.set(xlabel="omega [rad/s]", ylabel="relative error", ylim=(1e-4, None),
           title="Members' relative errors against the rational nominal, envelope and W")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "errors_and_weight.png"), dpi=120)
    plt.close(fig)

    s_nom, t_nom = nominal_curves
    fig, ax = plt.subplots(figsize=(8, 5))
    for i, loop in enumerate(loops):
        ax.loglog(OMEGA, np.abs(1 / (1 + loop)), color="tab:blue", lw=0.5, alpha=0.5,
                  label="members |S_i| (data)" if i == 0 else None)
        ax.loglog(OMEGA, np.abs(loop / (1 + loop)), color="tab:orange", lw=0.5, alpha=0.5,
                  label="members |T_i| (data)" if i == 0 else None)
    ax.loglog(w_dense, np.abs(s_nom), "b", lw=2, label="|S| nominal")
    ax.loglog(w_dense, np.abs(t_nom), color="darkorange", lw=2, label="|T| nominal")
    ax.loglog(w_dense, 1 / mag_w, "r--", lw=1.5, label="1/|W| (uncertainty)")
    import control as ct
    w1 = response(ct, design_info["W1"], w_dense)
    ax.loglog(w_dense, 1 / np.abs(w1), "g:", lw=1.5, label="1/|W1| (performance)")
    ax.set(xlabel="omega [rad/s]", ylabel="magnitude", ylim=(1e-4, 10),
           title=f"Sensitivity and complementary sensitivity (gamma {design_info['gamma']:.3f})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "sensitivity.png"), dpi=120)
    plt.close(fig)

    n = len(members)
    cols = 5 if n > 4 else n
    rows = int(math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    circle = np.exp(1j * np.linspace(0, 2 * np.pi, 200))
    for ax, d, loop, chk in zip(axes.ravel(), members, loops, checks):
        ax.plot(loop.real, loop.imag, "b", lw=1)
        ax.plot(loop.real, -loop.imag, "b:", lw=0.6)
        ax.plot(-1 + chk["modulus_margin"] * circle.real, chk["modulus_margin"] * circle.imag,
                "g--", lw=0.8)
        ax.plot([-1], [0], "r+", ms=10, mew=2)
        ax.set(xlim=(-2.5, 1.5), ylim=(-2.0, 2.0), aspect="equal",
               title=f"{d.name}: GM {chk['gain_margin_db']:.1f} dB, PM "
                     f"{chk['phase_margin_deg']:.0f} deg")
        ax.title.set_fontsize(8)
        ax.grid(True, alpha=0.3)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    fig.suptitle("Nyquist curves of L_i = Phi_i K from each member's measured FRF "
                 "(dashed circle: modulus margin)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "nyquist.png"), dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for m, t, y in steps:
        ax.plot(t, y, lw=1, label=m["name"])
    ax.set(xlabel="t [s]", ylabel="y", title="Step responses: each member's fitted model "
           f"(delay as Pade {SIM_PADE_ORDER}) with K")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "steps.png"), dpi=120)
    plt.close(fig)


# ----------------------------------------------------------------------------- report
def _f(x, digits=3):
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return f"{x:.{digits}g}"


def write_report(folder, command, s):
    c = s["cover"]
    d = s["design"]
    lines = [f"<!-- generated by: {command} -->", "",
             "# Robust design from measured FRFs: cover, H-infinity, check on the data", "",
             f"Plant family: {s['n_members']} measured-like units of a flexible structure "
             f"(three modes at {', '.join(_f(w) for w in WN)} rad/s, dampings "
             f"{', '.join(_f(z) for z in ZETA)}, delay {DELAY * 1e3:g} ms), stiffness spread "
             f"+-{STIFFNESS_SPREAD:.0%} (mode frequencies about +-12 %), damping spread "
             f"+-{DAMPING_SPREAD:.0%}, {NOISE:.0%} complex noise, {OMEGA.size} points "
             f"from {OMEGA[0]:g} to {OMEGA[-1]:g} rad/s; seed {s['seed']}. Runtime "
             f"{s['wall_time']:.0f} s.", "",
             *computed_on_lines(s.get("environment")),
             "## Nominal and cover", "",
             f"- Nominal: `fc.fit(nominal unit, n_sections=3)`: max rel. error "
             f"{_f(s['nominal']['max_rel_error'])}, delay {_f(s['nominal']['delay'] * 1e3, 4)} ms "
             f"(true {DELAY * 1e3:g} ms).",
             f"- Far factors moved to infinity before the design "
             f"(`roots_to_infinity`): {s['nominal']['moved']}.",
             f"- Cover: `fc.cover(model, members, pade_order={PADE_ORDER}, "
             f"tightness={COVER_TIGHTNESS:g})`: W of order "
             f"{c['order']}, stable {c['stable']}, minimum phase {c['minimum_phase']}; "
             f"median |W|/envelope {_f(c['median_ratio'])}, largest {_f(c['max_ratio'])}; "
             f"bounds every member at every point: {c['covers']}. {c['message']}.",
             f"- Pade error folded in: up to {_f(c['pade_error_max'])} over the band.", "",
             "![errors](errors_and_weight.png)", "",
             "## Controller", "",
             f"`control.mixsyn(G_R, W1, W2, W3=W)` with W1 = (s/{S_PEAK:g} + wb)/(s + wb "
             f"{S_FLOOR:g}), W2 = {KS_WEIGHT:g}, G_R the nominal with its delay as Pade "
             f"{PADE_ORDER}; the widest wb with gamma < 1 (tried, wb: gamma: "
             + ", ".join(f"{_f(w)}: {_f(g, 5)}" for w, g in d["tried"]) + "): "
             f"wb = {_f(d['bandwidth'])} rad/s, gamma = {d['gamma']:.4f}, controller order "
             f"{d['order']}, controller stable {d['stable']}.",
             f"- ||W T||_inf (models, python-control `linfnorm`) = {d['WT_inf']:.4f} < 1; "
             f"||W1 S||_inf = {d['W1S_inf']:.4f}.",
             "- Nominal margins (rational nominal): GM "
             f"{_f(d['nominal_margins']['gain_margin_db'])} dB, "
             f"PM {_f(d['nominal_margins']['phase_margin_deg'])} deg at "
             f"{_f(d['nominal_margins']['omega_crossover'])} rad/s, modulus margin "
             f"{_f(d['nominal_margins']['modulus_margin'])}.", "",
             "![S and T](sensitivity.png)", "",
             "## Robust stability on every member's measured FRF", "",
             "L_i(jw) = Phi_i(jw) K(jw) from the measured data and the exact controller (no "
             "fitted model). The open loop has no right-half-plane pole (stable plants, "
             f"controller poles: {d['controller_rhp_poles']} in the RHP), so the closed loop "
             "is stable iff the Nyquist curve of L_i does not encircle -1: winding number of "
             "1 + L_i over -inf..inf by conjugate symmetry (a whole number up to the ends, "
             "which are close to, not on, the real axis); below the first measured "
             "frequency the plant is held at its first measured value (its low-frequency "
             "plateau), above the last |L_i| is small (column |L(w_max)|). |W T| on the grid "
             "uses the nominal T. PM: at each gain crossover, the phase change of either "
             "sign that puts L_i on -1, the smallest over the crossovers (where |L_i| "
             "crosses 1 more than once, one crossing can lie near +1); delay margin: the "
             "smallest extra lag that reaches -1 at a crossover, over its frequency.", "",
             "| member | winding | closed-loop RHP poles | stable | GM [dB] | PM [deg] | "
             "crossover [rad/s] | modulus margin | delay margin [ms] | |L(w_max)| | "
             "max |W T| on grid |",
             "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for m in s["members"]:
        lines.append(
            f"| {m['name']} | {m['winding']:.3f} | {m['closed_loop_rhp_poles']} | "
            f"{'yes' if m['stable'] else 'NO'} | {_f(m['gain_margin_db'])} | "
            f"{_f(m['phase_margin_deg'])} | {_f(m['omega_crossover'])} | "
            f"{_f(m['modulus_margin'])} | {_f(m['delay_margin'] * 1e3)} | "
            f"{_f(m['loop_at_omega_max'])} | {_f(m['max_WT_on_grid'])} |")
    ok = all(m["stable"] for m in s["members"])
    lines += ["", f"**Robust stability on the data: {'passed' if ok else 'FAILED'}** for "
              f"{sum(m['stable'] for m in s['members'])} of {len(s['members'])} members; "
              f"smallest gain margin {_f(min(m['gain_margin_db'] for m in s['members']))} dB, "
              f"smallest phase margin {_f(min(m['phase_margin_deg'] for m in s['members']))} "
              f"deg, smallest modulus margin "
              f"{_f(min(m['modulus_margin'] for m in s['members']))}.", "",
              "![Nyquist](nyquist.png)", "",
              "## Step responses of the members' fitted models", "",
              "| member | fit max rel. error | fitted delay [ms] | closed loop stable | "
              "final value | overshoot [%] | 2 % settling [s] |",
              "|---|---:|---:|---|---:|---:|---:|"]
    for m in s["steps"]:
        lines.append(f"| {m['name']} | {_f(m['fit_max_rel_error'])} | "
                     f"{_f(m['fit_delay'] * 1e3, 4)} | {m['closed_loop_stable']} | "
                     f"{_f(m['final'])} | {_f(m['overshoot_pct'])} | "
                     f"{_f(m['settling_time'])} |")
    lines += ["", "The step at t = 0 is the Pade approximation's feedthrough (an even-order "
              "Pade all-pass has D = 1); the true delay holds y at 0 for "
              f"{DELAY * 1e3:g} ms. Settling times above a few seconds are the lightly "
              "damped modes' ripple around 2 % (the controller does not damp the modes: "
              "its bandwidth is below the first).", "", "![steps](steps.png)", ""]
    text = "\n".join(lines)
    with open(os.path.join(folder, "report.md"), "w", encoding="utf-8") as fh:
        fh.write(text)
    with open(os.path.join(folder, "report.json"), "w", encoding="utf-8") as fh:
        json.dump({k: v for k, v in s.items()}, fh, indent=1, default=float)


# ----------------------------------------------------------------------------- main
def run(folder, n_members, seed, command, progress):
    import control as ct

    t0 = time.perf_counter()
    nominal_data, members, params = family(n_members, seed)
    progress("fitting the nominal")
    nom = fc.fit(nominal_data, n_sections=3)
    progress(f"  max rel. error {nom.max_rel_error:.3g}, delay {nom.model.delay:.5g} s")
    progress("covering the family")
    # factors whose roots lie far above the band (a zero at 1e4 or 1e11 rad/s standing in
    # for the relative degree) moved to infinity: a better conditioned nominal; the cover
    # is taken against this model, so W includes what the move changes in the band
    nominal, moved = roots_to_infinity(nom.model, OMEGA[-1])
    progress(f"  {moved} far factor(s) moved to infinity")
    cov = fc.cover(nominal, members, pade_order=PADE_ORDER, tightness=COVER_TIGHTNESS)
    progress(f"  W order {cov.order}, median |W|/envelope {cov.median_ratio:.3g}")
    g_nom = cov.nominal_control()          # rational (Pade), balanced realization
    w_unc = cov.weight.to_control()        # W by sections (better scaled than weight_tf)
    progress("H-infinity design (mixsyn)")
    des = design(ct, g_nom, w_unc)
    k_sys = des["K"]
    loop_nom = ct.series(k_sys, g_nom)
    s_sys, t_sys = ct.feedback(1, loop_nom), ct.feedback(loop_nom, 1)
    w_dense = np.geomspace(OMEGA[0], OMEGA[-1], 2000)
    l_dense = response(ct, loop_nom, w_dense)
    n_open_rhp = int(np.sum(np.real(ct.poles(k_sys)) > 0))
    t_nom_grid = response(ct, t_sys, OMEGA)
    checks, loops = [], []
    for d in members:
        chk, loop = check_member(ct, d, k_sys, cov, t_nom_grid, n_open_rhp)
        checks.append(chk)
        loops.append(loop)
    progress("step responses of the members' fitted models")
    steps = step_responses(ct, members, k_sys, progress)
    figures(folder, cov, members, loops, checks,
            (1 / (1 + l_dense), l_dense / (1 + l_dense)), steps, des)
    summary = {
        "command": command, "seed": seed, "n_members": n_members, "member_params": params,
        "environment": environment(),
        "nominal": {"max_rel_error": float(nom.max_rel_error), "delay": nom.model.delay,
                    "beta": nominal.beta.tolist(), "moved": moved},
        "cover": {"order": cov.order, "median_ratio": cov.median_ratio,
                  "max_ratio": cov.max_ratio, "covers": cov.covers(),
                  "stable": cov.weight.is_stable(), "minimum_phase": cov.weight.is_minimum_phase(),
                  "message": cov.message, "median_ratios": cov.median_ratios,
                  "pade_error_max": float(np.max(cov.pade_error))},
        "design": {"bandwidth": des["bandwidth"], "gamma": des["gamma"], "tried": des["tried"],
                   "order": int(ct.ss(k_sys).nstates),
                   "stable": bool(np.all(np.real(ct.poles(k_sys)) < 0)),
                   "controller_rhp_poles": n_open_rhp,
                   "WT_inf": float(ct.linfnorm(ct.series(t_sys, w_unc))[0]),
                   "W1S_inf": float(ct.linfnorm(ct.series(s_sys, des["W1"]))[0]),
                   "nominal_margins": margins(w_dense, l_dense)},
        "members": checks, "steps": [m for m, _, _ in steps],
        "wall_time": time.perf_counter() - t0}
    write_report(folder, command, summary)
    return summary


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join("results", "robust"))
    ap.add_argument("--members", type=int, default=10, help="number of variants (>= 8)")
    ap.add_argument("--seed", type=int, default=29)
    args = ap.parse_args(argv)
    import matplotlib
    import warnings

    matplotlib.use("Agg")
    warnings.filterwarnings("ignore", category=FutureWarning, module="control")
    command = " ".join(["python scripts/robust_design.py"] + [shlex.quote(a) for a in argv])
    os.makedirs(args.out, exist_ok=True)
    s = run(args.out, args.members, args.seed, command,
            lambda line: print(line, file=sys.stderr))
    ok = all(m["stable"] for m in s["members"])
    print(f"robust stability on every member's data: {'passed' if ok else 'FAILED'}; "
          f"gamma {s['design']['gamma']:.4f}; report {os.path.join(args.out, 'report.md')}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

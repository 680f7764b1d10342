"""
To python-control, and a loop-shaping check
===========================================

``RationalDelayModel.to_control()`` gives the rational part as a python-control
``StateSpace`` (the delay in its ``delay`` attribute, or as a Padé approximation with
``pade_order=``). Here we fit a plant with a lightly damped mode and a 20 ms delay, design a
PI controller on the model, and check the loop's margins on the model and on the data.
"""

import control as ct
import matplotlib.pyplot as plt
import numpy as np

import freqid_casadi as fc

omega = np.logspace(-1, 2.3, 300)                         # rad/s
s = 1j * omega
measured = np.exp(-0.02 * s) * 2.0 / (s**2 / 4 + 1.4 * s / 2 + 1) / (s**2 / 900 + 0.04 * s / 30 + 1)
data = fc.FrequencyData(omega, measured, name="plant")

res = fc.fit(data, n_sections=2, start="best")
print(res.summary())
G = res.model.to_control(pade_order=6)                     # delay as a 6th-order Padé
print("states:", G.nstates, " delay kept in the model:", res.model.delay)

# %%
# A PI controller designed on the model; the closed loop in python-control (with the Padé
# delay) must have all its poles in the left half plane.
kp, ki = 0.3, 0.6
C = ct.tf([kp, ki], [1, 0])                          # kp + ki/s
T = ct.feedback(ct.ss(C) * G, 1)
p = T.poles()
print(f"closed loop: {p.size} poles, stable {bool(np.all(p.real < 0))}, "
      f"largest real part {p.real.max():.4f} rad/s")

# %%
# The same margins from the frequency responses themselves (exact delay, no Padé): the
# loop C(jw) Phi(jw) of the data and C(jw) G_N(jw) of the model, crossovers interpolated
# in log frequency.


def margins(loop):
    mag_db, phase = 20 * np.log10(np.abs(loop)), np.unwrap(np.angle(loop))
    lw = np.log(omega)
    i = np.flatnonzero(np.diff(np.sign(mag_db)))[0]            # gain crossover
    wc = np.interp(0.0, [mag_db[i + 1], mag_db[i]], [lw[i + 1], lw[i]])
    pm = np.degrees(np.pi + np.interp(wc, lw, phase))
    j = np.flatnonzero(np.diff(np.sign(phase + np.pi)))[0]     # phase crossover
    wp = np.interp(-np.pi, [phase[j + 1], phase[j]], [lw[j + 1], lw[j]])
    gm = -np.interp(wp, lw, mag_db)
    return gm, np.exp(wp), pm, np.exp(wc)


Ld = (kp + ki / s) * measured
Lm = (kp + ki / s) * res.model.frequency_response(omega)
for name, loop in (("data", Ld), ("model", Lm)):
    gm_db, wp, pm_deg, wc = margins(loop)
    print(f"{name:5s}: gain margin {gm_db:.2f} dB at {wp:.2f} rad/s, "
          f"phase margin {pm_deg:.2f} deg at {wc:.2f} rad/s")

# %%
# The closed-loop step response (python-control) and a Nyquist-style picture of both loops
# near the critical point.
t, y = ct.step_response(T, np.linspace(0, 15, 1500))
fig, ax = plt.subplots(layout="constrained")
ax.plot(t, y)
ax.set(xlabel="t (s)", ylabel="y", title="closed-loop step response of the model")
ax.grid(True)

# %%
# Both loops near the critical point -1.
fig, ax = plt.subplots(figsize=(5, 5), layout="constrained")
ax.plot(Ld.real, Ld.imag, lw=3, alpha=0.4, label="data")
ax.plot(Lm.real, Lm.imag, "--", label="model")
ax.plot([-1], [0], "r+", ms=12)
ax.set(xlim=(-2, 1), ylim=(-2, 1), xlabel="Re L", ylabel="Im L", title="loop C G")
ax.legend()
ax.grid(True)

"""
A modal test saved from MATLAB: every channel, and why their zeros are free
===========================================================================

A shaker drives a structure at one point and four accelerometers read it; the analyst
saves the FRF matrix as MATLAB's ``modalfrf`` returns it, ``frf`` (frequencies x
sensors) beside ``f`` in Hz. ``fc.load_all`` reads every channel of such a file, each
named as MATLAB indexes it (``frf(:,2)``); ``fc.load(path, parameter="frf(:,2)")`` reads
one. The first sensor sits at the drive (collocated: minimum phase); the others see the
modes with modal constants of either sign, and their FRFs have right-half-plane zeros.
A shared-pole fit whose channels are all held minimum phase cannot follow them: it ends
poor, its poles pulled away from the modes (the damping most), and its message offers
the fit with free zeros, which finds them (``freqid modal`` fits free zeros unless told
``--zeros minimum-phase``).
"""

import os
import tempfile

import numpy as np
import scipy.io

import freqid_casadi as fc

# three modes (10, 25, 45 Hz), four sensors; shape components of each mode by sensor
fn, zeta = np.array([10.0, 25.0, 45.0]), np.array([0.02, 0.015, 0.01])
phi = np.array([[1.0, 0.8, 0.5], [0.7, -0.4, -0.9], [0.4, -0.9, 0.6], [0.2, -0.5, 1.0]])
f = np.linspace(2.0, 60.0, 400)                                    # Hz
s, wn = 2j * np.pi * f[:, None], 2 * np.pi * fn
frf = sum(phi[:, k] * phi[0, k] / (s ** 2 + 2 * zeta[k] * wn[k] * s + wn[k] ** 2)
          for k in range(3))                                       # (400, 4)
rng = np.random.default_rng(1)
frf = frf * (1 + 0.005 * (rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape)))

path = os.path.join(tempfile.mkdtemp(), "test.mat")
scipy.io.savemat(path, {"f": f, "frf": frf})                       # as MATLAB saves it
datas = fc.load_all(path, freq_unit="Hz")
print([d.name for d in datas])

held = fc.fit_shared(datas, 3, delay=False)                        # minimum phase
print(held.status, "-", held.message.split(" — ")[-1])
free = fc.fit_shared(datas, 3, delay=False, zeros="free")
print(free.status, free.message)
for f0, z0, a, b in zip(fn, zeta, held.modes, free.modes):
    print(f"true {f0:g} Hz, zeta {100 * z0:g} %: minimum phase {a.frequency_hz:.4f} Hz, "
          f"{100 * a.zeta:.3f} %; free zeros {b.frequency_hz:.4f} Hz, {100 * b.zeta:.3f} %")

# %%
# The mode shapes (modal constants re-estimated at each fit's poles, largest component
# +1) against the truth: near 1 for both, the least-squares constants being robust to
# the poles' error; it is the poles, the damping above all, that the minimum-phase fit
# gets wrong.
true = phi.T / np.abs(phi.T).max(axis=1, keepdims=True)
for name, res in (("minimum phase", held), ("free zeros", free)):
    shapes = np.asarray(res.mode_shapes()).real
    signs = np.sign(np.sum(shapes * true, axis=1, keepdims=True))
    print(f"{name:14s} MAC with the truth:",
          np.round(np.diag(fc.mac(shapes * signs, true)), 5))

# %%
# The fourth sensor, far from the drive: data and both models. The minimum-phase model of
# this channel kept no zeros at all (all its numerators at their bound): its phase lies
# under the data's, its magnitude cannot follow them.
import matplotlib.pyplot as plt  # noqa: E402

d = datas[3]
fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.4, 5), sharex=True)
for res, style, label in ((held, "C3--", "minimum phase"), (free, "C0-", "free zeros")):
    g = res.models[3].frequency_response(d.omega)
    a1.loglog(f, np.abs(g), style, label=label)
    a2.semilogx(f, np.degrees(np.unwrap(np.angle(g))), style)
a1.loglog(f, np.abs(d.response), "k.", ms=2, label=d.name)
a2.semilogx(f, np.degrees(np.unwrap(np.angle(d.response))), "k.", ms=2)
a1.set_ylabel("|G|")
a2.set_ylabel("phase (deg)")
a2.set_xlabel("frequency (Hz)")
a2.xaxis.set_minor_formatter(plt.NullFormatter())
a2.set_xticks([2, 5, 10, 20, 50], ["2", "5", "10", "20", "50"])
a1.legend()
fig.tight_layout()

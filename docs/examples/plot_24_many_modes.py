"""
A structure with many modes: the automatic order
================================================

``n_sections="auto"`` fits 1, 2, ... sections and stops at the smallest order whose
residual is the data's noise. On a flexible structure with a dozen lightly damped modes
one more section is one more mode of twelve: it lowers the RMS by a few per cent until
the last modes are in, less than the 10 % the search asks of an order that does not yet
explain the data. So the search does not stop for want of improvement below as many
sections as the data show resonance peaks (``resonance_count``: a lower bound, since
close modes merge and the noise hides weak ones); the ``order-chosen`` record says how
many it counted, and why it stopped where it did.
"""

import numpy as np

import freqid_casadi as fc
from freqid_casadi import plots
from freqid_casadi.fitting.order import resonance_count

# a collocated measurement of a structure with 12 modes from 2 to 250 rad/s, 0.5 % noise
wn = np.array([2.0, 3.1, 5.5, 8.0, 13.0, 19.0, 30.0, 44.0, 70.0, 105.0, 160.0, 250.0])
zeta = np.array([0.02, 0.01, 0.03, 0.015, 0.02, 0.01, 0.025, 0.015, 0.02, 0.01, 0.03, 0.02])
residue = np.array([1.0, 0.4, 0.8, 0.5, 0.9, 0.3, 0.7, 0.5, 0.6, 0.4, 0.8, 0.6])
w = np.geomspace(0.7, 700, 250)
s = 1j * w
g = sum(r * x ** 2 / (s ** 2 + 2 * z * x * s + x ** 2) for r, x, z in zip(residue, wn, zeta))
rng = np.random.default_rng(1)
g = g * np.exp(-0.002 * s) * (1 + 0.005 * (rng.standard_normal(w.size)
                                           + 1j * rng.standard_normal(w.size)) / np.sqrt(2))
data = fc.FrequencyData(w, g, name="12-mode structure")
print("resonance peaks counted:", resonance_count(w, g))

res = fc.fit(data, n_sections="auto")
record = next(d for d in res.diagnostics if d.code == "order-chosen")
print(f"{res.model.n_sections} sections, status {res.status}, RMS {res.rms_rel_error:.3g}")
print(record.message)

# %%
# Every order the search fitted, its RMS and the peaks the data show: the first sections
# gain little each (a mode of twelve), then the RMS falls to the noise.
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots(figsize=(6, 3.5))
ax.semilogy(record.values["orders"], record.values["rms"], "o-", label="RMS of each order")
ax.axvline(record.values["resonance_peaks"], color="0.6", ls="--", label="peaks counted")
ax.axhline(0.005, color="C3", ls=":", label="noise (0.5 %)")
ax.set_xlabel("sections")
ax.set_ylabel("RMS relative error")
ax.legend()
fig.tight_layout()

# %%
# The chosen model on the data.
plots.bode(res)

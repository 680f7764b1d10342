"""
An analyser's noise floor: ``weights="noise"``
==============================================

An analyser's noise is mostly a floor of constant absolute level, so its relative level
grows as ``1 / |G|``: here 5000-fold over the band of a system with 74 dB of range. The
fit weighs every point's relative error alike, so the noisy points (the roll-off, the
antiresonance) decide it, and where the data are quiet the model stays far above their
noise: the status says "poor-fit" however many sections it has. ``weights="noise"`` fits
twice: without weights, then weighed by the inverse variance the first residual shows.

Three sections in the model class, judged against the true system in units of the true
noise (0.1-0.3 is a model at the noise floor).
"""

import numpy as np

import freqid_casadi as fc
from freqid_casadi import plots

w = np.logspace(0, 3, 300)
s = 1j * w


def system(s):
    """Two resonance/antiresonance pairs, a double pole at 30 rad/s and a 2 ms delay."""
    return ((s ** 2 / 50 ** 2 + 0.1 * s / 50 + 1) / (s ** 2 / 80 ** 2 + 0.04 * s / 80 + 1)
            * (s ** 2 / 300 ** 2 + 0.06 * s / 300 + 1)
            / (s ** 2 / 200 ** 2 + 0.02 * s / 200 + 1) * np.exp(-0.002 * s) / (s / 30 + 1) ** 2)


g = system(s)
floor = 3e-4 * np.median(np.abs(g))                  # the noise's absolute level (RMS)
rng = np.random.default_rng(0)
data = fc.FrequencyData(w, g + floor * (rng.standard_normal(w.size)
                                        + 1j * rng.standard_normal(w.size)) / np.sqrt(2),
                        name="noise floor")

fits = {"without weights": fc.fit(data, n_sections=3),
        'weights="noise"': fc.fit(data, n_sections=3, weights="noise")}
for label, res in fits.items():
    e = res.model.frequency_response(w) / g - 1
    units = np.sqrt(np.mean(np.abs(e) ** 2 / (floor / np.abs(g)) ** 2))
    print(f"{label:16s} {res.status}: residual {res.details['noise']['ratio']:.2f} times its "
          f"noise, {units:.2f} noise units from the true system")
print(next(d for d in fits['weights="noise"'].diagnostics if d.code == "noise-weights").message)

# %%
# Without weights the residual is a smooth trend below the first resonance, where the data
# are quiet; weighed by their noise it is the noise everywhere. Thin lines: the error
# against the true system between the samples.
plots.relative_error(list(fits.values()), labels=list(fits),
                     truth=lambda omega: system(1j * omega))

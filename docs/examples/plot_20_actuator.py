"""
A servo-hydraulic actuator, from its raw records
================================================

The package ships the raw DAQ records of a chirp test on a servo-hydraulic actuator
(``freqid_casadi/datasets/actuator``, MIT licence, see its ``SOURCE.md``): commanded and
measured displacement at 1000 Hz. From the records to a model:

1. the H1 estimate by Welch cross-spectra, with the coherence and the variance of every
   bin (``experiment.frf_from_records``), keeping the bins with coherence >= 0.99;
2. a fit with a delay, the better of the sequential and the rational start (``start="best"``,
   the default of ``freqid fit``).
"""

import freqid_casadi as fc
from freqid_casadi import experiment, plots

rec = experiment.actuator_records()
print(rec.fs, "Hz;", {k: v.size for k, v in rec.channels.items()})

est = experiment.frf_from_records(rec.channels["CHANNEL2"], rec.channels["CHANNEL0"],
                                  fs=rec.fs, estimator="h1", nperseg=8192,
                                  min_coherence=0.99, name="actuator H1")
data = est.data
print(data.omega.size, "frequencies from", round(data.omega[0] / 6.283, 3), "to",
      round(data.omega[-1] / 6.283, 2), "Hz")

# %%
# Two sections and a delay (the delay is the lag the model does not otherwise explain).
res = fc.fit(data, n_sections=2, start="best")
print(res.summary())
unc = res.uncertainty
print(f"delay {1e3 * res.model.delay:.2f} ms +- {1e3 * unc.delay_std:.2f} ms (1 std)")

# %%
plots.bode(res)
plots.relative_error(res)

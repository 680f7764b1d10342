"""
The thesis's MATLAB code, transcribed
=====================================

``studies.thesis_matlab`` transcribes Appendix A of the thesis (main.m, cost_and_coeffs.m,
create_jacob.m, tf_approx.m) line by line, so its numbers can be compared with the
package's on the same data. As printed it reproduces Table 4.1's row A at 17 sections in
about 190 000 LM iterations (several minutes; ``python scripts/thesis_matlab.py``). Here a
short run, 4 sections of example A under a time budget, beside IPOPT at the same order.
"""

import freqid_casadi as fc
from freqid_casadi import plots
from freqid_casadi.studies.thesis_matlab import run_thesis_matlab

data = fc.systems.G_A()
matlab = run_thesis_matlab(data, n_sections=4, integrator=True, time_budget=15.0)
print(f"transcription: {matlab.n_sections} sections, max rel. error {matlab.max_rel_error:.4g},"
      f" {matlab.nit} LM iterations, {matlab.wall_time:.1f} s, status {matlab.status}")
ours = fc.fit(data, n_sections=matlab.n_sections, integrator=True, start="sequential")
print(f"IPOPT:         {ours.model.n_sections} sections, max rel. error "
      f"{ours.max_rel_error:.4g}, {ours.nit} iterations, {ours.wall_time:.1f} s")

# %%
plots.bode(ours, models=[matlab.model], labels=["IPOPT", "thesis MATLAB"])

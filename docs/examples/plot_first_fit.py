"""
The first fit
=============

Fit the thesis's free-free beam.
"""
import freqid_casadi as fc
data = fc.systems.G_A()
res = fc.fit(data, n_sections=4, integrator=True)
print(res.summary())

"""
A batch of FRFs on Dask
=======================

``fitting.batch.fit_many`` fits many data sets with the same options, in local processes
(``jobs=``) or on a Dask cluster (``scheduler=`` an address or a ``distributed.Client``).
Results do not depend on where they ran: every fit is deterministic with single-threaded
BLAS. Here a small in-process Dask cluster fits the thesis's beam A and its +5 % / +10 %
perturbations (thesis fig. 4.8) at 4 sections; a bad item is reported, not raised.
"""

from distributed import Client, LocalCluster

import freqid_casadi as fc
from freqid_casadi import plots
from freqid_casadi.fitting.batch import fit_many

datas = [fc.systems.G_A(), fc.systems.perturbed("A", 5), fc.systems.perturbed("A", 10)]

with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                  dashboard_address=None) as cluster, Client(cluster) as client:
    items = fit_many(datas + ["no_such_file.csv"], scheduler=client, n_sections=4,
                     integrator=True)

for item in items:
    if item.result is not None:
        print(f"{item.name:28s} {item.status:10s} max rel. error {item.result.max_rel_error:.3g}")
    else:
        print(f"{item.name:28s} {item.status:10s} {item.error}")

# %%
plots.relative_error([it.result for it in items if it.result is not None],
                     labels=[it.name for it in items if it.result is not None])

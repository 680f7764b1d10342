"""freqid_casadi: stable, minimum-phase low-order models with delay from frequency data.

Fits ``G_N(s) = exp(-h s) K [1/s] prod_k (a s^2 + 2 zn wn s + wn^2)/(b s^2 + 2 zd wd s + wd^2)``
to frequency-response samples by minimising the relative error, every stage a CasADi NLP
with true bounds ``beta >= 0`` solved by IPOPT (see ``docs/spec.md``).

Quick start::

    import freqid_casadi as fc
    data = fc.systems.G_A()                      # free-free beam, 500 points
    res = fc.fit(data, n_sections=17, integrator=True)
    res.status, res.message                      # "ok": the model explains the data
    res.max_rel_error, res.model.delay, res.model.to_control()

Robust control: ``fc.cover(model, [data, ...])`` gives one stable, minimum-phase weight
``W(s)`` bounding the relative error of every member of a plant family (MATLAB's
``ucover``); ``model.to_control(delay="pade", pade_order=k)`` a rational nominal.

Importing this package does not import matplotlib (plots are in ``freqid_casadi.plots``).
"""

from . import systems
from .core.data import FrequencyData
from .errors import DataError, FreqidError, OptionError, SolverError, StructureError
from .fitting.fit import FitResult, FitStatus, StageRecord, fit
from .io.loaders import (DataWarning, load, load_all, load_csv, load_mat, load_npz,
                         load_text, load_touchstone, load_uff, save_csv)
from .core.model import RationalDelayModel, Structure
from .core.modes import ModeShapes, mac
from .modal.survey import stabilization
from .modal.shared import SharedFitResult, fit_shared
from .options import (BarrierLMOptions, FitOptions, IpoptOptions, LoopOptions,
                      VectorFittingOptions)
from .uncertainty.cover import CoverResult, cover

__all__ = [
    "fit", "FitResult", "FitStatus", "StageRecord", "IpoptOptions", "BarrierLMOptions",
    "LoopOptions",
    "FitOptions", "VectorFittingOptions", "FrequencyData", "RationalDelayModel", "Structure",
    "load", "load_all", "load_csv", "load_npz", "load_text", "load_mat", "load_uff",
    "load_touchstone", "save_csv",
    "DataWarning", "systems",
    "FreqidError", "DataError", "StructureError", "OptionError", "SolverError",
    "fit_shared", "SharedFitResult", "stabilization", "mac", "ModeShapes",
    "cover", "CoverResult",
]
__version__ = "0.1.0"

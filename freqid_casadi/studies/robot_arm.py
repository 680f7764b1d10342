"""The DaISy flexible robot arm (data set 96-009), the experiments: FRF estimate, fits
against order with the resolution safeguard, the chosen order and its uncertainty weight.

:func:`run_robot_arm` returns a :class:`RobotArmStudy`; the report folder is
:mod:`freqid_casadi.studies.robot_arm_report` (``scripts/robot_arm.py``).

Data: B. De Moor et al., DaISy: Database for the Identification of Systems, data set 96-009.
"""

import dataclasses

import numpy as np

from .. import experiment
from ..core.data import FrequencyData
from ..fitting.fit import fit
from ..report.formatting import number
from ..core.metrics import relative_error
from ..uncertainty.weight import fit_uncertainty_weight
from ..fitting.validation import prune_sections

__all__ = ["run_robot_arm", "RobotArmStudy", "arm_data", "low_frequency", "scan", "choose",
           "CITATION", "WITHIN", "CRITERION", "WEIGHT_ORDER"]

CITATION = ("B. De Moor et al., DaISy: Database for the Identification of Systems, "
            "data set 96-009 (flexible robot arm), KU Leuven.")
#: An order is acceptable when its RMS relative error is within this factor of the best.
WITHIN = 1.25
#: The criterion of the choice (the max is set by one or two bins at the antiresonance
#: near 1.12 rad/sample, where |G| ~ 0.02 and the single-period estimate is noisy).
CRITERION = "rms_rel_error"
#: Order of the multiplicative uncertainty weight W.
WEIGHT_ORDER = 2


def arm_data(path=None):
    """The arm's FRF estimate and the data to fit (sign flipped, see :func:`low_frequency`).

    Parameters
    ----------
    path : str, optional
        The DaISy file (default: the package's copy, :func:`freqid_casadi.experiment.robot_arm`).

    Returns
    -------
    (FrfEstimate, FrequencyData)
    """
    est = experiment.robot_arm(path)
    d = est.data
    return est, FrequencyData(d.omega, -d.response, "robot arm, -G (DaISy 96-009)",
                              unit=d.unit)


def low_frequency(est, n=6):
    """Evidence for the structure at low frequency: |G| and arg G over the first n bins.

    A flat magnitude (no 1/omega rise) means no integrator; a phase near +-180 degrees
    means a negative static gain, which the model class (K >= 0) cannot represent, so -G
    is fitted (the model of G is -G_N).

    Parameters
    ----------
    est : FrfEstimate
        The arm's estimate.
    n : int
        Number of bins.

    Returns
    -------
    dict
        Bins, omega (rad/sample), magnitude, phase (degrees) and the two ratios.
    """
    g = est.data.response[:n]
    mag = np.abs(g)
    return {"bins": est.bins[:n].tolist(), "omega": est.data.omega[:n].tolist(),
            "magnitude": mag.tolist(), "phase_deg": np.degrees(np.angle(g)).tolist(),
            "magnitude_ratio_last_first": float(mag[-1] / mag[0]),
            "omega_ratio_last_first": float(est.data.omega[n - 1] / est.data.omega[0])}


def _validated(res):
    """(FitResult of the safeguarded model, PruneResult): near-cancelling pole/zero pairs
    narrower than the bin spacing are removed and the rest refitted
    (:func:`freqid_casadi.fitting.validation.prune_sections`)."""
    pr = prune_sections(res)
    if not pr.removed:
        return res, pr
    err = relative_error(pr.model, res.data)
    return dataclasses.replace(res, model=pr.model, rel_error=err.values,
                               max_rel_error=err.max, rms_rel_error=err.rms), pr


def scan(data, orders, delays=(False, True), progress=None):
    """Fit every (delay, n_sections) and apply the resolution safeguard.

    Parameters
    ----------
    data : FrequencyData
        The data to fit (-G).
    orders : sequence of int
        Numbers of sections.
    delays : sequence of bool
        With and/or without a fitted delay.
    progress : callable, optional
        Receives one line (str) per fit.

    Returns
    -------
    (list of dict, dict)
        One JSON-ready row per fit, and the safeguarded FitResult by (delay, n).
    """
    rows, results = [], {}
    for delay in delays:
        for n in orders:
            raw = fit(data, n_sections=n, integrator=False, delay=delay, start="sequential")
            res, pr = _validated(raw)
            results[(delay, n)] = res
            rows.append({"delay": delay, "n_sections": n, "order": 2 * n,
                         "raw_max_rel_error": raw.max_rel_error,
                         "raw_rms_rel_error": raw.rms_rel_error,
                         "removed_pairs": [f.as_dict() for f in pr.removed],
                         "removed_text": [f.text(data.unit) for f in pr.removed],
                         "n_sections_kept": res.model.n_sections,
                         "resolved_after": pr.check.ok,
                         "max_rel_error": res.max_rel_error,
                         "rms_rel_error": res.rms_rel_error,
                         "max_dense_change": pr.max_dense_change,
                         "delay_estimate": res.model.delay, "success": raw.success,
                         "stable": res.model.is_stable(),
                         "minimum_phase": res.model.is_minimum_phase(),
                         "wall_time": raw.wall_time})
            if progress is not None:
                progress(f"delay={delay} n={n}: max {number(raw.max_rel_error)} -> "
                         f"{number(res.max_rel_error)} after removing {len(pr.removed)} "
                         f"pair(s), h {number(res.model.delay)}")
    return rows, results


def choose(rows, within=WITHIN, criterion=CRITERION):
    """The smallest number of sections (no-delay model preferred on ties) whose
    ``criterion`` (of the safeguarded model) is within ``within`` x the best over all rows.

    Parameters
    ----------
    rows : list of dict
        The rows of :func:`scan`.
    within : float
        Factor over the best value.
    criterion : str
        Row key compared ("rms_rel_error").

    Returns
    -------
    (dict, float)
        The chosen row and the best value of ``criterion``.
    """
    best = min(r[criterion] for r in rows)
    ok = [r for r in rows if r[criterion] <= within * best]
    pick = min(ok, key=lambda r: (r["n_sections"], r["delay"], r[criterion]))
    return pick, best


@dataclasses.dataclass(frozen=True, eq=False)
class RobotArmStudy:
    """What :func:`run_robot_arm` measured.

    Attributes
    ----------
    estimate : FrfEstimate
        The FRF estimate of G (odd bins, rad/sample).
    data : FrequencyData
        -G, the data fitted.
    rows : list of dict
        One per (delay, sections) fit (:func:`scan`).
    results : dict
        The safeguarded FitResult by (delay, sections).
    chosen : dict
        The chosen row (:func:`choose`).
    best : float
        The best RMS relative error over all rows.
    weight : UncertaintyWeight
        The multiplicative uncertainty weight of the chosen model.
    """

    estimate: object
    data: object
    rows: list
    results: dict
    chosen: dict
    best: float
    weight: object

    @property
    def model(self):
        """The chosen (safeguarded) FitResult."""
        return self.results[(self.chosen["delay"], self.chosen["n_sections"])]


def run_robot_arm(orders=(1, 2, 3, 4, 5), *, path=None, delays=(False, True), progress=None):
    """Fit the arm at every order, choose one, and bound its error by a weight.

    Parameters
    ----------
    orders : sequence of int
        Numbers of sections to fit.
    path : str, optional
        The DaISy file (default: the package's copy).
    delays, progress
        As in :func:`scan`.

    Returns
    -------
    RobotArmStudy
    """
    est, data = arm_data(path)
    rows, results = scan(data, orders, delays, progress)
    pick, best = choose(rows)
    res = results[(pick["delay"], pick["n_sections"])]
    weight = fit_uncertainty_weight(res, order=WEIGHT_ORDER)
    return RobotArmStudy(est, data, rows, results, pick, best, weight)

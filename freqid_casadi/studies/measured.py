"""Measured data end to end, the experiments: the actuator chirp test from its raw records
and the DaISy robot arm, each fitted at several orders beside the outside peers.

:func:`run_measured` returns a :class:`MeasuredStudy`; the report folder is
:mod:`freqid_casadi.studies.measured_report` (``scripts/measured.py``). The peers are
scikit-rf's vector fitting (the ``[peers]`` extra) and scipy's AAA, at the same order;
neither is constrained to be stable or minimum phase, which the table states per model.

Data: the actuator chirp test (MIT, github.com/DanielMaurelE/vRTHS_AMBC_MRdamper, shipped in
``freqid_casadi/datasets/actuator``); B. De Moor et al., DaISy: Database for the
Identification of Systems, data set 96-009 (robot arm, shipped in ``datasets``).
"""

import time
from dataclasses import dataclass, field

import numpy as np

from .. import experiment
from ..baselines import aaa
from ..core.data import FrequencyData
from ..errors import FreqidError
from ..fitting.fit import fit
from ..core.metrics import relative_error

__all__ = ["MeasuredStudy", "DataSetStudy", "run_measured", "actuator_frf", "fit_row",
           "peer_row", "ACTUATOR", "ROBOT_ARM", "DELAY_UNITS"]

#: The actuator's Welch settings and fits: 14 averages of 8192 samples (0.122 Hz bins),
#: the band where the coherence is >= 0.99 (0.12-20.3 Hz; it drops to 0.96 by 20.8 Hz at
#: the end of the chirp), 1 to 3 sections with a delay.
ACTUATOR = {"nperseg": 8192, "min_coherence": 0.99, "sections": (1, 2, 3),
            "input": "CHANNEL2", "output": "CHANNEL0"}
#: The robot arm: 1 to 5 sections, no integrator, with a delay; the sign of the gain is
#: left to ``gain_sign="auto"`` (its static gain is negative).
ROBOT_ARM = {"sections": (1, 2, 3, 4, 5)}


@dataclass(frozen=True)
class DataSetStudy:
    """Fits of one data set.

    Attributes
    ----------
    name : str
    data : FrequencyData
    rows : tuple of dict
        One JSON-ready row per model: ``method`` ("freqid", "skrf-vector-fitting",
        "aaa"), ``n_sections`` (order = 2 n_sections), max/RMS relative error, delay and
        its standard deviation (freqid), stable, minimum phase, success and diagnostics.
    models : dict
        ``(method, n_sections) -> model`` (RationalDelayModel or StateSpaceModel).
    estimate : FrfEstimate or None
        The FRF estimate with its coherence (actuator) or bins (robot arm).
    notes : tuple of str
    """

    name: str
    data: object
    rows: tuple
    models: dict
    estimate: object = None
    notes: tuple = ()


@dataclass(frozen=True)
class MeasuredStudy:
    """Both data sets (:func:`run_measured`).

    Attributes
    ----------
    actuator, robot_arm : DataSetStudy
    settings : dict
        :data:`ACTUATOR` and :data:`ROBOT_ARM` as run.
    wall_time : float
        Seconds.
    """

    actuator: DataSetStudy
    robot_arm: DataSetStudy
    settings: dict = field(default_factory=dict)
    wall_time: float = 0.0


def actuator_frf(nperseg=ACTUATOR["nperseg"], min_coherence=ACTUATOR["min_coherence"]):
    """The actuator's H1 estimate (commanded -> measured displacement) from the raw records.

    Parameters
    ----------
    nperseg : int
        Welch segment length (samples at 1000 Hz).
    min_coherence : float
        Keep the frequencies where the coherence is at least this.

    Returns
    -------
    FrfEstimate
    """
    rec = experiment.actuator_records()
    u, y = rec.channels[ACTUATOR["input"]], rec.channels[ACTUATOR["output"]]
    return experiment.frf_from_records(u, y, fs=rec.fs, estimator="h1", nperseg=nperseg,
                                       min_coherence=min_coherence,
                                       name="actuator, H1 (commanded -> measured)")


def fit_row(data, n_sections, **options):
    """Fit ``data`` with ``n_sections`` (delay, start="best") and tabulate the result.

    Parameters
    ----------
    data : FrequencyData
    n_sections : int
    **options
        More keywords of :func:`freqid_casadi.fit`.

    Returns
    -------
    (dict, FitResult)
    """
    res = fit(data, n_sections=n_sections, delay=True, start="best", **options)
    try:
        delay_std = float(res.uncertainty.delay_std)
    except FreqidError:
        delay_std = float("nan")
    row = {"method": "freqid", "n_sections": n_sections, "order": 2 * n_sections,
           "max_rel_error": res.max_rel_error, "rms_rel_error": res.rms_rel_error,
           "delay": res.model.delay, "delay_std": delay_std, "gain": res.model.gain,
           "stable": res.model.is_stable(), "minimum_phase": res.model.is_minimum_phase(),
           "success": res.success, "start": res.start, "nit": res.nit,
           "wall_time": res.wall_time,
           "diagnostics": [d.as_dict() for d in res.diagnostics]}
    return row, res


def peer_row(data, n_sections, method):
    """A peer's model of the same order (2 ``n_sections`` poles) and its row.

    Parameters
    ----------
    data : FrequencyData
    n_sections : int
    method : {"skrf-vector-fitting", "aaa"}

    Returns
    -------
    (dict, StateSpaceModel or None)
        The row says ``"error"`` if the peer failed or is not installed.
    """
    from ..baselines import skrf_vector_fitting

    make = {"skrf-vector-fitting": skrf_vector_fitting, "aaa": aaa}[method]
    t0 = time.perf_counter()
    try:
        model = make(data, 2 * n_sections)
        err = relative_error(model, data)
    except (FreqidError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return {"method": method, "n_sections": n_sections, "order": 2 * n_sections,
                "error": str(exc)}, None
    return {"method": method, "n_sections": n_sections, "order": 2 * n_sections,
            "max_rel_error": err.max, "rms_rel_error": err.rms, "delay": 0.0,
            "stable": bool(model.is_stable()),
            "minimum_phase": bool(model.is_minimum_phase()), "success": None,
            "wall_time": time.perf_counter() - t0}, model


#: Delay unit per data set: (scale, unit); the robot arm's frequency is normalised
#: (rad/sample), so its delay is in samples.
DELAY_UNITS = {"actuator": (1e3, "ms"), "robot arm": (1.0, "samples")}


def _study(name, data, sections, estimate, notes, progress):
    rows, models = [], {}
    for n in sections:
        row, res = fit_row(data, n)
        rows.append(row)
        models[("freqid", n)] = res
        scale, unit = DELAY_UNITS[name]
        progress(f"{name}: {n} section(s): max {row['max_rel_error']:.4g}, delay "
                 f"{row['delay'] * scale:.4g} {unit}, success {row['success']}")
        for method in ("skrf-vector-fitting", "aaa"):
            prow, model = peer_row(data, n, method)
            rows.append(prow)
            models[(method, n)] = model
    return DataSetStudy(name, data, tuple(rows), models, estimate, tuple(notes))


def run_measured(progress=None):
    """Run both data sets (a few seconds each on a 2-core machine).

    Parameters
    ----------
    progress : callable, optional
        Receives one line (str) per fit.

    Returns
    -------
    MeasuredStudy
    """
    progress = progress or (lambda line: None)
    t0 = time.perf_counter()
    est = actuator_frf()
    band = est.data.omega / (2 * np.pi)
    # the package's measure is the unweighted relative error (the estimate's weights,
    # |H|^2/variance, are an option of fit; here every frequency counts the same)
    data = FrequencyData(est.data.omega, est.data.response, est.data.name, unit=est.data.unit)
    act = _study("actuator", data, ACTUATOR["sections"], est,
                 [f"H1 from {ACTUATOR['input']} (commanded) to {ACTUATOR['output']} "
                  f"(measured displacement), Welch nperseg {ACTUATOR['nperseg']} "
                  f"({est.n_averages} averages), coherence >= {ACTUATOR['min_coherence']} "
                  f"on {band[0]:.3g}-{band[-1]:.3g} Hz ({est.data.n_points} frequencies)"],
                 progress)
    arm_est = experiment.robot_arm()
    arm = _study("robot arm", arm_est.data, ROBOT_ARM["sections"], arm_est,
                 ["normalised frequency (rad/sample), one period of 1024 samples, odd "
                  "bins; the gain sign is found by fit(gain_sign='auto')"], progress)
    return MeasuredStudy(act, arm, {"actuator": dict(ACTUATOR), "robot_arm": dict(ROBOT_ARM)},
                         time.perf_counter() - t0)

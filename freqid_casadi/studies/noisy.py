"""Example A on noisy data, the experiments: error against the clean system at and between
the samples.

1. G_A on the thesis's grid (500 points) times ``1 + n_i``, ``n_i`` complex Gaussian with
   RMS 2 % (seed 0); fit at the thesis's order (17 sections, integrator, delay).
2. Error against the *clean* G_A at the data points and on a 10x denser log grid, before
   and after the safeguard :func:`freqid_casadi.fitting.validation.prune_sections` (removes zero/
   pole pairs that nearly cancel and are narrower than the frequency spacing, then refits),
   and of the fit at the same order with the damping floor ``min_damping="auto"`` (no pole
   or zero narrower than the spacing, imposed in every stage NLP).
3. Weighted fitting: noise whose RMS grows from 0.5 % (low frequency) to 8 % (high
   frequency), fitted with uniform weights and with ``w_i = 1 / sigma_i^2`` (relative
   variance, normalised to mean 1), plain, pruned and with the damping floor.

:func:`run_noisy` returns a :class:`NoisyStudy`; the report folder is
:mod:`freqid_casadi.studies.noisy_report` (``scripts/noisy_example.py``).
"""

from dataclasses import dataclass

import numpy as np

from .. import systems
from ..core.data import FrequencyData, dense_grid
from ..fitting.fit import fit
from ..options import LoopOptions
from ..core.metrics import relative_error
from ..fitting.validation import check_resolution, prune_sections

__all__ = ["run_noisy", "NoisyStudy", "noisy_data", "clean_errors", "study", "SEED", "NOISE",
           "SIGMA_RANGE", "DENSE"]

SEED = 0
NOISE = 0.02
SIGMA_RANGE = (0.005, 0.08)
DENSE = 10


def noisy_data(sigma, seed=SEED, name=None):
    """G_A on the thesis grid times (1 + n), n complex Gaussian: ``E|n_i|^2 = sigma_i^2``.

    Parameters
    ----------
    sigma : float or ndarray of float, shape (500,)
        Noise RMS (relative), one value or one per point.
    seed : int
        Seed of ``numpy.random.default_rng``.
    name : str, optional
        Name of the noisy data (default ``"G_A + 2 % noise"``).

    Returns
    -------
    (FrequencyData, FrequencyData)
        The clean and the noisy data.
    """
    clean = systems.G_A()
    rng = np.random.default_rng(seed)
    m = clean.n_points
    n = (rng.standard_normal(m) + 1j * rng.standard_normal(m)) / np.sqrt(2)
    return clean, FrequencyData(clean.omega, clean.response * (1 + sigma * n),
                                name or f"G_A + {100 * NOISE:g} % noise")


def clean_errors(model, clean, dense):
    """Relative errors |G_A / G_N - 1| against the clean system.

    Parameters
    ----------
    model : RationalDelayModel
    clean : FrequencyData
        The clean G_A at the samples.
    dense : ndarray of float, shape (K,)
        The dense grid (rad/s).

    Returns
    -------
    (ndarray, ndarray)
        The errors at the samples, shape (M,), and on the dense grid, shape (K,).
    """
    e_s = relative_error(model, clean).values
    e_d = relative_error(model, dense, systems.G_A(omega=dense).response).values
    return e_s, e_d


def _stats(e):
    return {"max": float(np.max(e)), "rms": float(np.sqrt(np.mean(e ** 2)))}


def study(data, clean, dense, n_sections, weights=None, floor=False):
    """Fit, errors against the clean system before/after the safeguard (pruning), and,
    with ``floor``, of the fit with the damping floor ``min_damping="auto"``.

    Parameters
    ----------
    data, clean : FrequencyData
        The noisy data fitted and the clean system at the same points.
    dense : ndarray of float, shape (K,)
        The dense grid (rad/s).
    n_sections : int
        Sections of the fits (integrator and delay included).
    weights : ndarray of float, shape (M,), optional
        Weights of the fit.
    floor : bool
        Also fit with ``min_damping="auto"``.

    Returns
    -------
    (dict, FitResult, PruneResult, tuple, tuple)
        The JSON-ready numbers (with ``"_floor_errors"`` when ``floor``), the plain fit,
        the pruned one, and the clean errors before and after pruning
        (:func:`clean_errors`).
    """
    # the plain fit is the subject: without the resolution guard (fitting.guard), which
    # would refit it with the damping floor
    res = fit(data, n_sections=n_sections, integrator=True, delay=True, weights=weights,
              start="sequential", loop=LoopOptions(resolution_guard=False))
    check = check_resolution(res, data.omega)
    pr = prune_sections(res, reference=lambda w: systems.G_A(omega=w), dense_factor=DENSE)
    before = clean_errors(res.model, clean, dense)
    after = clean_errors(pr.model, clean, dense)
    out = {
        "n_sections": n_sections, "wall_time": res.wall_time, "success": res.success,
        "fit_max_rel_error_vs_noisy": res.max_rel_error,
        "fit_rms_rel_error_vs_noisy": res.rms_rel_error,
        "n_flagged_pairs": len(check.flags),
        "flagged": [f.as_dict() for f in check.flags],
        "flagged_text": [f.text() for f in check.flags],
        "min_zeta_flagged": min([min(f.zero.zeta, f.pole.zeta) for f in check.flags],
                                default=None),
        "n_unresolved": len(check.unresolved),
        "unresolved_text": [f"{q.kind} {q.omega:.4g} rad/s zeta {q.zeta:.2g}"
                            for q in check.unresolved],
        "n_sections_after": pr.model.n_sections, "resolved_after": pr.check.ok,
        "refit_success": pr.refit_success,
        "after_max_rel_error_vs_noisy": pr.max_rel_error_after,
        "after_rms_rel_error_vs_noisy": pr.rms_rel_error_after,
        "clean_before": {"samples": _stats(before[0]), "dense": _stats(before[1])},
        "clean_after": {"samples": _stats(after[0]), "dense": _stats(after[1])},
        "max_dense_change": pr.max_dense_change,
    }
    if floor:
        rf = fit(data, n_sections=n_sections, integrator=True, delay=True, weights=weights,
                 min_damping="auto", start="sequential")
        fe = clean_errors(rf.model, clean, dense)
        out["floor"] = {
            "n_sections": rf.model.n_sections, "zeta_min": rf.zeta_min,
            "wall_time": rf.wall_time, "success": rf.success,
            "resolution_ok": rf.resolution.ok, "n_flagged_pairs": len(rf.resolution.flags),
            "fit_max_rel_error_vs_noisy": rf.max_rel_error,
            "fit_rms_rel_error_vs_noisy": rf.rms_rel_error,
            "clean": {"samples": _stats(fe[0]), "dense": _stats(fe[1])},
            "model": rf.model.to_dict()}
        out["_floor_errors"] = fe
    return out, res, pr, before, after


@dataclass(frozen=True, eq=False)
class NoisyStudy:
    """What :func:`run_noisy` measured.

    Attributes
    ----------
    summary : dict
        JSON-ready numbers: seed, noise RMS and max, grid sizes, ``noisy`` (the 2 % study:
        plain fit, flagged pairs, pruned fit, damping floor; errors against the clean
        system at the samples and on the dense grid), ``clean_fit`` (the floor's price on
        clean data), the plain and safeguarded models, ``weighted_study`` (RMS errors by
        band), ``uniform`` and ``weighted`` (the frequency-dependent-noise studies).
    curves : dict
        For the figures: ``omega`` and ``dense`` (rad/s), the clean errors ``before``,
        ``after`` (pruned) and ``floor`` as (samples, dense) pairs, ``sigma`` (noise RMS per
        point) and ``uniform`` / ``weighted`` (the damping-floor fits' errors).
    """

    summary: dict
    curves: dict


def _band_effect(clean, ua, wa):
    """RMS clean error below 1 rad/s and above 100 rad/s, uniform against weighted."""
    lo, hi = clean.omega < 1.0, clean.omega > 100
    return {
        "uniform_rms_below_1rad": float(np.sqrt(np.mean(ua[0][lo] ** 2))),
        "weighted_rms_below_1rad": float(np.sqrt(np.mean(wa[0][lo] ** 2))),
        "uniform_rms_above_100rad": float(np.sqrt(np.mean(ua[0][hi] ** 2))),
        "weighted_rms_above_100rad": float(np.sqrt(np.mean(wa[0][hi] ** 2))),
    }


def run_noisy(n_sections=17):
    """Run the noisy-data study at ``n_sections`` sections (default: the thesis's 17).

    Parameters
    ----------
    n_sections : int
        Sections of every fit.

    Returns
    -------
    NoisyStudy
    """
    clean, data = noisy_data(NOISE)
    dense = dense_grid(clean.omega, DENSE)
    noise = data.response / clean.response - 1
    main_study, res, pr, before, after = study(data, clean, dense, n_sections, floor=True)
    floor_err = main_study.pop("_floor_errors")
    clean_fit = {k: fit(clean, n_sections=n_sections, integrator=True, delay=True,
                        min_damping=md, start="sequential").max_rel_error
                 for k, md in (("plain", None), ("floor", "auto"))}
    sigma = np.logspace(np.log10(SIGMA_RANGE[0]), np.log10(SIGMA_RANGE[1]), clean.n_points)
    _, data2 = noisy_data(sigma, seed=1, name="G_A + frequency-dependent noise")
    w = 1.0 / sigma ** 2
    w = w / w.mean()
    uni, *_ = study(data2, clean, dense, n_sections, floor=True)
    wtd, *_ = study(data2, clean, dense, n_sections, weights=w, floor=True)
    ua, wa = uni.pop("_floor_errors"), wtd.pop("_floor_errors")
    summary = {
        "seed": SEED, "noise_rms_nominal": NOISE,
        "noise_rms": float(np.sqrt(np.mean(np.abs(noise) ** 2))),
        "noise_max": float(np.max(np.abs(noise))), "n_points": clean.n_points,
        "n_dense": int(dense.size), "noisy": main_study, "clean_fit": clean_fit,
        "safeguarded_model": pr.model.to_dict(), "plain_model": res.model.to_dict(),
        "weighted_study": {"sigma_range": list(SIGMA_RANGE), "seed": 1,
                           **_band_effect(clean, ua, wa)},
        "uniform": uni, "weighted": wtd,
    }
    curves = {"omega": clean.omega, "dense": dense, "before": before, "after": after,
              "floor": floor_err, "sigma": sigma, "uniform": ua, "weighted": wa}
    return NoisyStudy(summary, curves)

"""The resolution guard of :func:`~freqid_casadi.fitting.fit.fit` (layer L4): on noisy data
no pole or zero narrower than the data resolve, unless the data determine it.

A least-squares fit of noisy data with many sections can spend a section on the noise: a
near-cancelling pole/zero pair, or an undamped peak, narrower than the frequency spacing,
that passes through one noisy sample and is not there between the samples (example A with
2 % noise at 17 sections: 0.058 against the true system at the samples, 2.5 between them).
The data cannot tell such a feature from the noise. When the fit's resolution check fails
and ``min_damping`` was not given, :func:`guard_resolution` refits with the damping floor
of the frequency resolution (``min_damping="auto"``: no pole or zero narrower than the
spacing) and keeps that fit when it still explains the data to their noise (its residual
consistent with the noise, :mod:`~freqid_casadi.fitting.verdict`, and its RMS within
:data:`GUARD_RMS_FACTOR` of the free fit's): the narrow feature was then not determined by
the data (example A at 2 %: 0.045 at the samples and 0.048 between them). When the floor
costs more than the noise allows (exact data: A's own lightest modes are narrower than its
grid, 4.8e-14 free against 7e-4 with the floor), the data determine the feature and the
free fit stays (``LoopOptions(resolution_guard=False)`` skips the guard). Either way
``FitResult.details["resolution_guard"]`` says what was done
and ``alternatives`` holds the fit that was not kept.
"""

import dataclasses
import math
import warnings

from ..errors import FreqidError, ResolutionWarning
from .verdict import ROUNDING_RMS, FitStatus

__all__ = ["guard_resolution", "GUARD_RMS_FACTOR", "warn_unresolved"]

#: The floored fit is kept only if its RMS error is at most this factor times the free
#: fit's (both at the noise: the floor may cost a few per cent of the noise, not more).
GUARD_RMS_FACTOR = 1.25


def guard_resolution(result, refit, min_damping):
    """``result``, or its refit with the damping floor when that explains the data too.

    Parameters
    ----------
    result : FitResult
        The fit as asked for.
    refit : callable
        ``refit(min_damping)`` runs the same fit with that ``min_damping``, quietly.
    min_damping : None, str or float
        The user's ``min_damping``: the guard acts only when it is None (and the floor
        needs ``result.method == "ipopt"``).

    Returns
    -------
    (FitResult, bool)
        The fit kept, and whether it is the floored refit (then the caller drops the
        first fit's ResolutionWarning).
    """
    check = result.resolution
    loop = result.options.loop if result.options is not None else None
    if (min_damping is not None or check is None or check.ok or result.method != "ipopt"
            or loop is None or not loop.resolution_guard or loop.gauge != "dc"
            or not result.success
            or result.model.structure.basis != "second-order"):
        return result, False
    try:
        with warnings.catch_warnings():       # a fit the user did not ask for: quiet
            warnings.simplefilter("ignore")
            floored = refit("auto")
    except FreqidError:
        return result, False
    # "explains the data to their noise": its residual is consistent with the noise and no
    # larger than the free fit's beyond the noise's own scatter; its convergence flag is
    # not asked (at the floor's active constraints the termination test may end at the
    # iteration limit at the same point, depending on the BLAS kernel: measured on noisy
    # A, RMS 0.0187443 both ways, "ok" on one kernel, the iteration limit under Prescott)
    noise = floored.details.get("noise") or {}
    kept = (bool(noise.get("consistent")) and floored.resolution is not None
            and floored.resolution.ok and floored.status != FitStatus.POOR_FIT
            and floored.rms_rel_error <= GUARD_RMS_FACTOR * result.rms_rel_error)
    record = {"unresolved_features": len(check.flags) + len(check.unresolved),
              "free_rms_rel_error": result.rms_rel_error,
              "floored_rms_rel_error": floored.rms_rel_error,
              "floored_status": FitStatus(floored.status).value,
              "zeta_min": floored.zeta_min, "kept": "floored" if kept else "free"}
    if not kept:
        return dataclasses.replace(
            result, details=dict(result.details, resolution_guard=record),
            alternatives=dict(result.alternatives, **{"min_damping=auto": floored})), False
    note = (f"; {record['unresolved_features']} pole(s)/zero(s) narrower than the frequency "
            f"spacing were not determined by the data (free fit RMS "
            f"{result.rms_rel_error:.3g}, floored RMS {floored.rms_rel_error:.3g}, both within "
            f"the noise): held to the spacing (min_damping='auto', zeta >= "
            f"{floored.zeta_min:.3g}); pass loop=LoopOptions(resolution_guard=False) to "
            "keep the free fit (FitResult.alternatives['min_damping=None'] holds it)")
    return dataclasses.replace(
        floored, message=floored.message + note,
        details=dict(floored.details, resolution_guard=record),
        alternatives=dict(floored.alternatives, **{"min_damping=None": result})), True


def warn_unresolved(result, stacklevel):
    """The ResolutionWarning of a fit whose :func:`~freqid_casadi.fitting.validation.
    check_resolution` failed (nothing for None or a passed check; ``stacklevel`` of the
    warning).

    Its advice follows the cause, which the residual tells: on a fit exact to rounding
    (RMS <= ROUNDING_RMS) the pairs are spare sections, which a damping floor does not
    remove; on a fit at the noise (the residual's RMS at most CONSISTENT_RATIO times the
    noise its point-to-point differences show: the verdict's ``details["noise"]
    ["consistent"]``) they are features between the samples
    that the noisy data do not determine; otherwise the residual is systematic (a fit
    stopped on its way, or a model that misses something), and the pairs are sections the
    fit has not yet put where the data determine them.

    Parameters
    ----------
    result : FitResult
    stacklevel : int
        Of the warning (the caller's depth below the user's call).
    """
    check = result.resolution
    if check is None or check.ok:
        return
    noise = (result.details or {}).get("noise", {})
    ratio = float(noise.get("ratio", math.nan))
    prune = "freqid_casadi.fitting.validation.prune_sections"
    given = getattr(getattr(result, "options", None), "min_damping", None) is not None
    zeta = getattr(result, "zeta_min", 0) or 0
    floor = (f"the damping floor given (zeta >= {zeta:.3g}) follows the median spacing, "
             "wider than the spacing there" if given else
             "refit with min_damping='auto' (a damping floor from the frequency spacing)")
    if result.rms_rel_error <= ROUNDING_RMS:
        why = ("the fit is exact to rounding, so these are spare sections (more than the "
               "data need), placed where the data do not determine them; fit fewer "
               f"sections, or remove them with {prune} (FitResult.resolution lists them)")
    elif noise.get("consistent"):
        why = ("features between the samples that the noisy data do not determine (the "
               f"residual is at the noise: RMS {ratio:.3g} times it); inspect "
               f"FitResult.resolution; {floor}; remove them with {prune}, or fit fewer "
               "sections")
    else:
        level = (f"RMS {ratio:.3g} times the noise its point-to-point differences show"
                 if math.isfinite(ratio) else "no noise level could be estimated")
        why = (f"features between the samples that the data do not determine, beside a "
               f"residual that is not noise ({level}): the fit "
               f"{'stopped on its way' if not result.success else 'misses something'}, and "
               "these are sections it has not put where the data determine them; inspect "
               "FitResult.resolution and FitResult.message, "
               + ("continue the fit (a higher final_max_iter), " if not result.success
                  else "") +
               f"fit fewer sections, or remove them with {prune}"
               + ("" if given else ", or refit with min_damping='auto'"))
    warnings.warn(
        f"the model has {len(check.flags)} near-cancelling pole/zero pair(s) and "
        f"{len(check.unresolved)} pole(s)/zero(s) narrower than the frequency spacing: "
        + why, ResolutionWarning, stacklevel=stacklevel)

"""What the data say about the model class, before and after a fit (layer L4).

The package fits ``G_N(s) = exp(-h s) K [1/s] P_N(s)`` with P_N stable and (by default)
minimum phase and K > 0. Measured data can lie outside that class: a sign-inverted
sensor (phase near +-180 deg at low frequency), non-collocated sensors or an accelerance
with right-half-plane zeros, a delay larger than the frequency spacing can resolve. A fit
then returns its best effort, which may explain nothing. Each check here turns such a
finding into a :class:`Diagnostic` record (``code``, ``message``, ``values``) that
:func:`freqid_casadi.fit` stores in ``FitResult.diagnostics`` and the CLI prints.

Codes
-----
``negative-gain``
    The rational start explains the data far better with a negative gain than with a
    positive one (:func:`rational_gain_sign`; when it does not decide, the low-frequency
    phase, integrator removed, is near +-180 deg). With ``gain_sign="auto"`` the fit uses a
    negative gain and says so.
``non-minimum-phase``
    Excess phase that a delay cannot explain: a stable rational fit of the same order with
    free zeros (vector fitting at the fitted delay, or the rational start with free zeros,
    which searches the delay) needs right-half-plane zeros and is much more accurate than
    the minimum-phase fit. With ``zeros="free"`` the record states
    the fitted model's right-half-plane zeros instead.
``delay-undetermined``
    The delay sits at its upper bound pi / max(diff(omega)) (beyond it the phase is
    ambiguous between samples: aliased), or its phase ``h * omega_max`` is below the
    phase scatter of the residuals (the data do not resolve it).
``no-better-than-trivial``
    The RMS relative error is near 1: the model explains no more than the infinite-gain
    model (for which ``Phi/G_N - 1 = -1``). Such a fit is never a success.
``root-below-band``
    A pole or zero far below the lowest data frequency, which the data cannot tell from
    one at 0: a pole there stands for an integrator (the fit stops it at the floor of
    :attr:`~freqid_casadi.options.LoopOptions.root_floor` instead of letting it creep),
    a zero for a differentiator.
``integrator``
    With ``gain_sign="positive"`` forced: the lowest bins, the model's poles at the origin
    removed, look like poles or zeros at the origin the model lacks rather than a negative
    gain (phase within 30 deg of +-90 deg, or of 180 deg with a magnitude going as
    omega^+-2); the record names the ``integrator=`` to pass. ``integrator="auto"``
    states its choice in a record of this code too
    (:func:`~freqid_casadi.fitting.origin.origin_diagnostics`).
"""

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..core.data import FrequencyData
from ..core.metrics import relative_error
from ..core.model import MAX_ORIGIN_ORDER, times_jw_power

__all__ = ["Diagnostic", "CODES", "TRIVIAL_RMS", "low_frequency_phase", "low_frequency_slope",
           "check_gain_sign", "gain_sign_decision", "rational_gain_sign",
           "check_trivial", "check_delay", "check_minimum_phase", "rhp_zeros_note",
           "check_roots_below_band", "BELOW_BAND", "spell_origin", "low_frequency_line"]

CODES = ("negative-gain", "non-minimum-phase", "delay-undetermined", "no-better-than-trivial",
         "root-below-band", "order-chosen", "integrator", "noise-weights")

#: Low-frequency phase (deg, integrator removed) within which flat data (log-log slope
#: within 0.5) have a positive gain without asking the fits (:func:`check_gain_sign`).
CLEAR_PHASE_DEG = 45.0

#: Error of a rational start that explains the data exactly (to rounding): the gain-sign
#: check (:func:`rational_gain_sign`, its max relative error) and ``integrator="auto"``
#: (:data:`~freqid_casadi.fitting.origin.DECISIVE_RMS`, its RMS) then do not try the other
#: sign.
EXACT_START = 1e-8

#: Fraction of the lowest data frequency below which a root is "far below the band".
BELOW_BAND = 0.01

#: The poles (k > 0) or zeros (k < 0) at the origin whose minimum-phase rational starts
#: :func:`check_minimum_phase` compares with the free-zeros start (right-half-plane zeros
#: at the bottom of the band can mimic zeros at the origin, an accelerance's s^2 at k = 0).
ORIGIN_ORDERS = (0, 1, -1, 2, -2)

#: RMS relative error at or above which a model is "no better than trivial": the
#: infinite-gain model has RMS exactly 1.
TRIVIAL_RMS = 0.75


@dataclass(frozen=True)
class Diagnostic:
    """One finding about the data or the fitted model.

    Attributes
    ----------
    code : str
        One of :data:`CODES`.
    message : str
        One or two sentences with the numbers and what to do.
    severity : {"info", "warning", "error"}
        "error": the result does not represent the data (``success`` is False);
        "warning": the result is usable but outside what was asked or assumed;
        "info": a choice the fit made for the user (e.g. a negative gain).
    values : dict
        The numbers behind the message (floats, ints, lists), for reports and JSON.
    """

    code: str
    message: str
    severity: str = "warning"
    values: dict = field(default_factory=dict)

    def as_dict(self):
        """Plain-JSON form."""
        return {"code": self.code, "severity": self.severity, "message": self.message,
                "values": dict(self.values)}

    def __str__(self):
        return f"{self.code}: {self.message}"


def spell_origin(k):
    """How ``integrator=`` spells k poles at the origin.

    Parameters
    ----------
    k : int
        Poles at the origin (negative: zeros).

    Returns
    -------
    str
        "False", "True" or the integer.
    """
    return "True" if k == 1 else "False" if k == 0 else str(int(k))


def _low_points(omega, n_min=3, n_max=20, fraction=0.05):
    """How many of the lowest points the low-frequency phase and slope use.

    Parameters
    ----------
    omega : ndarray, shape (n,)
        The data's frequencies (rad/s), ascending.
    n_min : int, optional
        Fewest points.
    n_max : int or None, optional
        Most points (None: no limit, a share of the points whatever their number).
    fraction : float, optional
        Share of the points (5 %).

    Returns
    -------
    int
        ``round(fraction * n)`` within ``[n_min, n_max]``, at most ``n``.
    """
    m = max(int(round(fraction * omega.size)), n_min)
    return min(m if n_max is None else min(m, n_max), omega.size)


def low_frequency_phase(data, integrator, delay=0.0):
    """Phase (rad) of the data's static part at the lowest frequencies.

    The integrator's -90 deg is removed (the response is multiplied by ``j omega``); the
    phase is the angle of the mean unit phasor over the lowest 5 % of the points (3 to 20
    points), so single noisy samples and the small low-frequency delay phase do not decide.

    Parameters
    ----------
    data : FrequencyData
    integrator : bool or int
        Poles at the origin to remove (negative: zeros).
    delay : float, optional
        A delay (s) to remove too (the response is multiplied by ``exp(j omega delay)``):
        a band that starts far from 0 can carry turns of delay phase at its lowest bins.

    Returns
    -------
    float
        In (-pi, pi]; near 0 for a positive static gain, near +-pi for a negative one.
    """
    m = _low_points(data.omega)
    g = data.response[:m]
    k = int(integrator)
    if k == 1:
        g = g * 1j * data.omega[:m]
    elif k:
        g = times_jw_power(g, data.omega[:m], k)
    # no division (subnormal or huge responses)
    unit = np.exp(1j * (np.angle(g) + data.omega[:m] * float(delay)))
    return float(np.angle(np.mean(unit)))


def low_frequency_slope(data, integrator):
    """Log-log slope of |G| (integrator removed) over the lowest 5 % of the points
    (:func:`low_frequency_line`): about 0 for a static gain, +k for k zeros at the origin
    (e.g. +2 for an accelerance of a free or lightly supported structure).

    Parameters
    ----------
    data : FrequencyData
    integrator : bool

    Returns
    -------
    float
        d log|G| / d log omega (nan with fewer than 2 distinct points).
    """
    return low_frequency_line(data, integrator)[0]


def low_frequency_line(data, integrator):
    """The line :func:`low_frequency_slope` fits to ``log|G|`` over the lowest points: its
    slope and the RMS scatter of the points about it (natural log of ``|G|``).

    Parameters
    ----------
    data : FrequencyData
    integrator : bool or int
        Poles at the origin to remove (negative: zeros).

    Returns
    -------
    (float, float)
        Slope and scatter (both nan with fewer than 2 distinct points).

    Notes
    -----
    The line is fitted to the lowest 5 % of the points however many there are: the band
    is then the same at every density of a grid. At most 20 points, as the phase takes
    (:func:`low_frequency_phase`: the lowest bins, where a delay has the least phase),
    spanned a band too narrow for a slope on dense data, and the noise decided it: 100
    corpus cases resampled at 1600, 6400 and 20 000 points proposed other candidates of
    ``integrator="auto"`` than at 400 points in 22, 32 and 44; as a share, in 1 each.
    """
    m = max(_low_points(data.omega, n_max=None), 2)
    if data.omega.size < 2:
        return float("nan"), float("nan")
    log_w = np.log(data.omega[:m])
    with np.errstate(divide="ignore"):      # logs: no overflow at extreme scales
        k = int(integrator)
        log_g = np.log(np.abs(data.response[:m])) + (log_w if k == 1 else k * log_w)
    line = np.polyfit(log_w, log_g, 1)
    with np.errstate(invalid="ignore"):
        scatter = np.sqrt(np.mean((log_g - np.polyval(line, log_w)) ** 2))
    return float(line[0]), float(scatter)


def rational_gain_sign(data, structure, decisive=0.5):
    """The gain sign under which the rational start explains the data, or None.

    The rational start (:func:`~freqid_casadi.fitting.start.rational_start`: vector
    fitting with the delay refined from the right-half-plane zeros, the zeros reflected,
    the gain in closed form; no IPOPT) is run on the data, on a frequency axis scaled by a
    power of two; unless it is exact (max relative error below :data:`EXACT_START`), also
    on the negated data. The sign whose start has the lower error wins if that error is
    below ``decisive`` times the other's. (A positive start below 0.5 once decided alone:
    on a 140-220 GHz transmission measurement, tx190_s21 at 5 sections, the positive
    start's 0.44 then hid the negative one's 0.025, and the fit ended at RMS 0.0166
    instead of 0.0073.) Unlike the phase at the lowest bins (which a delay and
    a pole below the band turn past -90 deg, and an accelerance's zeros at the origin to
    180 deg), this is the sign the model class fits.

    Parameters
    ----------
    data : FrequencyData
    structure : Structure
        The model to fit (sections, basis, integrator, delay; minimum-phase zeros).
    decisive : float
        The largest ratio of the winner's error to the loser's.

    Returns
    -------
    (int, float, float) or None
        The sign and the starts' max relative errors with K > 0 and K < 0 (NaN for a
        start not run); None when neither start is usable or the errors do not decide.
    """
    from ..core.resolution import default_delay_max
    from ..core.scaling import reference_scales, scale_data
    from .start import RationalStartError, rational_start

    w_ref, g_ref = reference_scales(data)
    scaled = scale_data(data, w_ref, g_ref)
    dmax = default_delay_max(scaled.omega)

    def error(sign):
        target = FrequencyData(scaled.omega, sign * scaled.response, None, scaled.weights)
        try:
            with np.errstate(all="ignore"):
                err = rational_start(target, structure, delay_max=dmax).max_rel_error
        except (RationalStartError, ValueError, ArithmeticError, np.linalg.LinAlgError):
            return math.inf
        return float(err) if math.isfinite(err) else math.inf

    pos = error(1)
    if pos < EXACT_START:
        return 1, pos, math.nan
    neg = error(-1)
    if neg <= decisive * pos and math.isfinite(neg):
        return -1, pos, neg
    if pos <= decisive * neg and math.isfinite(pos):
        return 1, pos, neg
    return None


def check_gain_sign(data, integrator, gain_sign="auto", structure=None):
    """The gain sign to fit, and the record that says why.

    Parameters
    ----------
    data : FrequencyData
    integrator : bool
    gain_sign : {"auto", "positive", "negative"}
        "auto": positive when the data are flat and within :data:`CLEAR_PHASE_DEG` of 0 deg
        at the lowest bins, with a delay whose phase there is below that too (a delay of
        more than half a turn at the band edge is estimated from the group delay and its
        phase removed); else the sign under which the rational start of ``structure``
        explains the data (:func:`rational_gain_sign`; with free zeros too: the static
        gain's sign is K's whatever the zeros, and on the corpus's 63 non-minimum-phase or
        many-turn-delayed cases the starts' sign took free-zeros fits at the noise from 59
        to 61 and statuses "ok" from 50 to 58), or, without ``structure`` or when that does
        not decide, the sign of the low-frequency response (phase within 90 deg of 0:
        positive; of 180 deg: negative).
    structure : Structure, optional
        The model to fit.

    Returns
    -------
    sign : int
        +1 or -1.
    diagnostics : tuple of Diagnostic
        A ``negative-gain`` record when the data look sign-inverted: "info" when the fit
        uses the negative gain, "warning" when ``gain_sign="positive"`` forces the other.
    """
    sign, found, _ = gain_sign_decision(data, integrator, gain_sign, structure)
    return sign, found


def gain_sign_decision(data, integrator, gain_sign="auto", structure=None):
    """:func:`check_gain_sign`, and whether the sign is a guess: the rational starts were
    asked (``gain_sign="auto"``, a ``structure``, data not clearly positive) and did not
    decide, so the sign is the low-frequency phase's.

    Parameters
    ----------
    data, integrator, gain_sign, structure
        As for :func:`check_gain_sign`.

    Returns
    -------
    (int, tuple of Diagnostic, bool)
        The sign, the diagnostics, and True when the sign is that guess (a caller may then
        fit both signs, as ``fit`` does).
    """
    # a delay of more than half a turn at the band edge (the rational start's threshold)
    # is estimated from the group delay and its phase removed from the lowest bins: a
    # band far from 0 (linear spacing) can carry turns of delay phase there
    from .start import significant_group_delay

    h = significant_group_delay(data)
    phase = low_frequency_phase(data, integrator, h)
    deg = math.degrees(phase)
    slope = low_frequency_slope(data, integrator)
    m = _low_points(data.omega)
    values = {"low_frequency_phase_deg": deg, "n_points": m,
              "omega_max_used": float(data.omega[m - 1]), "low_frequency_slope": slope,
              "delay_removed": h}
    rational = None
    # flat and in phase at the lowest bins: positive without a doubt (a stable minimum-
    # phase factor with a flat magnitude has no phase there, Bode's gain-phase relation);
    # otherwise the phase may come from a delay and poles below the band, or from zeros
    # at the origin, and the fits decide
    clear = (abs(deg) <= CLEAR_PHASE_DEG and abs(slope) <= 0.5
             and math.degrees(h * values["omega_max_used"]) <= CLEAR_PHASE_DEG)
    asked = structure is not None and gain_sign == "auto" and not clear
    if asked:
        rational = rational_gain_sign(data, structure)
    undecided = asked and rational is None
    if rational is not None:
        looks_negative = rational[0] < 0
        values.update(rational_sign=rational[0], rational_max_rel_error_positive=rational[1],
                      rational_max_rel_error_negative=rational[2])
        why = (f"the rational start explains the data with a negative gain (max rel. error "
               f"{rational[2]:.2g}) far better than with a positive one "
               f"({rational[1]:.2g}): the static gain is negative (the low-frequency phase "
               f"is {deg:.1f} deg)")
    else:
        looks_negative = abs(phase) > math.pi / 2
        what = "".join(f"with {x} removed, " for x, on in
                       (("the integrator", integrator), (f"the delay {h:.4g} s", h)) if on)
        origin = (f" (the magnitude rises as omega^{slope:.1f} there: part of this phase "
                  "comes from zeros at the origin, as in an accelerance, which the unit-DC "
                  "factors can only approach; dividing the data by (j omega)^k before "
                  "fitting is the cleaner model)" if abs(slope) > 0.5 else "")
        why = (f"the low-frequency phase ({what}lowest {values['n_points']} points up to "
               f"{values['omega_max_used']:.4g} {data.unit}) is {deg:.1f} deg, near "
               f"+-180 deg: the static gain is negative{origin}")
    if gain_sign == "negative" or (gain_sign == "auto" and looks_negative):
        if not looks_negative:
            return -1, (), False
        msg = (f"{why}; fitted with a negative gain (gain_sign='auto'; pass "
               "gain_sign='positive' to force K > 0)")
        return -1, (Diagnostic("negative-gain", msg, "info", values),), undecided
    if looks_negative:
        # (K > 0 forced: the rational starts were not asked, the phase decided)
        missing = _origin_mismatch(deg, slope)
        if missing:
            return 1, (_origin_mismatch_record(values, integrator, missing, what,
                                               data.unit),), False
        msg = (f"{why}: the data look sign-inverted but gain_sign='positive' forces K > 0, "
               "so the fit must explain a 180 deg phase it cannot; use gain_sign='auto' or "
               "'negative'")
        return 1, (Diagnostic("negative-gain", msg, "warning", values),), False
    return 1, (), undecided


#: Low-frequency log-log slope beyond which a phase near 180 deg is read as two roots at
#: the origin the model lacks rather than a negative gain (:func:`_origin_mismatch`; a
#: double integrator read over the lowest bins of a corpus system: -1.2, an accelerance's
#: two zeros: +2.4, a negative static gain: within 0.5).
ORIGIN_SLOPE = 1.0
#: Distance (deg) from +-90 deg (one root at the origin) and from 180 deg (two roots, or a
#: negative gain) within which the low-frequency phase is read (:func:`_origin_mismatch`).
ORIGIN_PHASE_DEG = 30.0


def _origin_mismatch(deg, slope):
    """For data whose low-frequency phase (the model's roots at the origin removed) is
    beyond +-90 deg: the nonzero ``m`` when they behave as ``(j omega)^m`` there rather
    than as a negative gain, else 0. A static gain of either sign has 0 or 180 deg: a
    phase within :data:`ORIGIN_PHASE_DEG` of +-90 deg is one root at the origin (``m =
    -1`` for a pole, -90 deg); within it of 180 deg, a magnitude that falls or rises
    faster than omega^:data:`ORIGIN_SLOPE` is two (``m = -2``: poles, ``+2``: zeros).
    Between the two (a negative gain with a lag from dynamics near the band's bottom, or
    a root at the origin with a lead) the phase does not tell, and the sign's reading
    stands."""
    if not math.isfinite(deg):
        return 0
    if abs(deg) <= 90.0 + ORIGIN_PHASE_DEG:
        return -1 if deg < 0 else 1
    if (abs(deg) >= 180.0 - ORIGIN_PHASE_DEG and math.isfinite(slope)
            and abs(slope) > ORIGIN_SLOPE):
        return 2 if slope > 0 else -2
    return 0


def _origin_mismatch_record(values, integrator, m, what, unit):
    """The ``integrator`` warning of a fit whose data, with the model's ``integrator``
    removed, behave as ``(j omega)^m`` at the lowest bins (:func:`_origin_mismatch`),
    where a forced positive gain would otherwise read their phase as a sign (values: the
    sign check's, ``origin_mismatch`` m and ``suggested_integrator``)."""
    k = int(integrator)
    wanted = k - m
    count = f"{abs(m)} more {'pole' if m < 0 else 'zero'}{'s' * (abs(m) != 1)}"
    msg = (f"the low-frequency phase ({what}lowest {values['n_points']} points up to "
           f"{values['omega_max_used']:.4g} {unit}) is {values['low_frequency_phase_deg']:.1f} "
           f"deg and |G| goes as omega^{values['low_frequency_slope']:.1f} there: the data "
           f"have {count} at the origin than integrator={spell_origin(k)} gives the model "
           "(a static gain of either sign is flat there, at 0 or 180 deg); pass "
           f"integrator={spell_origin(wanted)}, or integrator='auto' to choose")
    return Diagnostic("integrator", msg, "warning",
                      dict(values, origin_mismatch=int(m), suggested_integrator=int(wanted)))


def check_trivial(max_rel_error, rms_rel_error, threshold=TRIVIAL_RMS):
    """A ``no-better-than-trivial`` record if the RMS relative error is >= ``threshold``.

    The infinite-gain model has ``Phi/G_N - 1 = -1`` at every point (RMS exactly 1); a
    model near it explains nothing, whatever the optimiser's status.

    Parameters
    ----------
    max_rel_error, rms_rel_error : float
        The fit's errors (a NaN counts as trivial).
    threshold : float
        Default :data:`TRIVIAL_RMS`.

    Returns
    -------
    tuple of Diagnostic
    """
    if not (rms_rel_error >= threshold) and math.isfinite(rms_rel_error):
        return ()
    msg = (f"RMS relative error {rms_rel_error:.3g} (max {max_rel_error:.3g}) is near 1, "
           "the error of the trivial infinite-gain model: the model explains (almost) "
           "nothing of the data; see the other diagnostics for why (sign, non-minimum "
           "phase, delay), or check the data (units, columns, which channel is the input)")
    return (Diagnostic("no-better-than-trivial", msg, "error",
                       {"rms_rel_error": float(rms_rel_error),
                        "max_rel_error": float(max_rel_error), "threshold": threshold}),)


def _residual_phase_scatter(model, data):
    ratio = data.response / model.frequency_response(data.omega)
    return float(np.sqrt(np.mean(np.angle(ratio) ** 2)))


def check_delay(model, data, delay_max, rms_rel_error=None, *, delay_std=None, at_bound=0.98,
                poor_rms=0.3):
    """``delay-undetermined`` records for a fitted model with a delay.

    Parameters
    ----------
    model : RationalDelayModel
    data : FrequencyData
    delay_max : float
        The delay's upper bound (s), normally ``pi / max(diff(omega))``.
    rms_rel_error : float, optional
        The fit's RMS relative error: a poor fit (>= ``poor_rms``) with the delay in the
        upper half of its range is flagged too (a delay beyond the bound, aliased).
    delay_std : float, optional
        The delay's standard deviation (s) from the fit's parameter covariance
        (:mod:`freqid_casadi.uncertainty.covariance`): a delay whose std exceeds
        half its value is not
        determined by the data (typically traded against a zero far above the band).
    at_bound : float
        Fraction of ``delay_max`` from which the delay counts as at its bound.
    poor_rms : float
        RMS relative error from which a fit counts as poor.

    Returns
    -------
    tuple of Diagnostic
    """
    if not model.structure.delay:
        return ()
    h = model.delay
    w_max = float(data.omega[-1])
    tu = data.time_unit
    values = {"delay": h, "delay_max": float(delay_max), "phase_at_omega_max_rad": h * w_max}
    if h >= at_bound * delay_max:
        msg = (f"the delay {h:.6g} {tu} is at its upper bound pi/max(diff(omega)) = "
               f"{delay_max:.6g} {tu}: beyond it the phase is ambiguous between samples "
               "(aliased), so the data cannot determine the delay; sample the frequency "
               "axis more densely, or fix the delay (delay=False, or a known value "
               "removed from the data)")
        return (Diagnostic("delay-undetermined", msg, "warning", values),)
    if rms_rel_error is not None and rms_rel_error >= poor_rms and h >= 0.5 * delay_max:
        msg = (f"the fit is poor (RMS relative error {rms_rel_error:.3g}) with the delay "
               f"{h:.6g} {tu} at {100 * h / delay_max:.0f} % of the largest resolvable "
               f"delay pi/max(diff(omega)) = {delay_max:.6g} {tu}: the data's delay may be larger "
               "than the frequency spacing can resolve (aliased phase); sample the "
               "frequency axis more densely or remove a known delay from the data")
        values["rms_rel_error"] = float(rms_rel_error)
        return (Diagnostic("delay-undetermined", msg, "warning", values),)
    if delay_std is not None and h > 0 and not delay_std <= 0.5 * h:
        values["delay_std"] = float(delay_std)
        msg = (f"the delay {h:.6g} {tu} has a standard deviation of {delay_std:.3g} {tu} from "
               "the fit's parameter covariance: the data do not determine it (it trades "
               "against other parameters, typically a zero far above the band); fit fewer "
               "sections, fix the delay, or read it as a lag of the model, not a "
               "measured dead time")
        return (Diagnostic("delay-undetermined", msg, "warning", values),)
    scatter = _residual_phase_scatter(model, data)
    values["residual_phase_rms_rad"] = scatter
    if 0 < h * w_max < scatter:
        msg = (f"the delay {h:.4g} {tu} turns the phase by only {h * w_max:.3g} rad at the "
               f"highest frequency, less than the residuals' phase scatter ({scatter:.3g} "
               "rad RMS): the data do not determine it")
        return (Diagnostic("delay-undetermined", msg, "warning", values),)
    return ()


def _vf_free_zeros(data, model, n_poles, delay=None):
    """Vector fit with stable poles and free zeros of the data with a delay (default the
    model's) and the model's integrator removed; returns (max, rms relative error, RHP
    zeros) or None."""
    from ..baselines import vector_fitting

    s = 1j * data.omega
    base = data.response * np.exp(s * (model.delay if delay is None else delay))
    if model.origin_order == 1:
        base = base * s
    elif model.origin_order:
        base = times_jw_power(base, data.omega, model.origin_order)
    try:
        target = FrequencyData(data.omega, base)
        vf = vector_fitting(target, n_poles, n_iter=10, enforce_stable_poles=True)
        err = relative_error(vf, target)
        zeros = np.asarray(vf.zeros(), complex)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(err.values)):
        return None
    zeros = zeros[np.isfinite(zeros)]
    # right-half-plane zeros beyond the band act like a delay there (their phase is nearly
    # linear in omega below |z|): only those inside the band are excess phase
    rhp = zeros[(zeros.real > 0) & (np.abs(zeros) <= data.omega[-1])]
    return err.max, err.rms, rhp


def _freqs(roots):
    return ", ".join(f"{abs(r):.4g}" for r in sorted(roots, key=abs)
                     if r.imag >= 0)


def check_minimum_phase(model, data, max_rel_error, rms_rel_error, *, ratio=0.5,
                        floor=0.02):
    """``non-minimum-phase`` record: excess phase a delay cannot explain.

    A stable rational model of the same order with free zeros (relaxed vector fitting
    with pole flipping, at the fitted delay and at none) is compared with the
    minimum-phase fit. If it needs right-half-plane zeros inside the band (``|z| <=
    omega_max``; zeros beyond it act like a delay there) and reaches an RMS relative error
    below ``ratio`` times the fit's (and the fit's RMS is above ``floor``), the data have
    excess phase. When those vector fittings do not show it, the rational start with free
    zeros (:func:`~freqid_casadi.fitting.start.rational_start`, which searches the delay
    itself; at the model's k and at k = 0, either gain sign) is compared the same way: a
    poor minimum-phase fit may hold a delay far from the data's, which the fixed-delay
    fittings inherit (4 non-collocated holdout cases at RMS 0.4-0.98 whose free-zeros
    starts reach 0.002-0.014). That start must also beat by ``ratio`` the starts with
    minimum-phase zeros, at those k and at every k of :data:`ORIGIN_ORDERS`: where one
    does as well, the fit is poor (a local minimum of the sequential start) or its poles at
    the origin are not the data's, not the zeros' half plane.

    Parameters
    ----------
    model : RationalDelayModel
        The minimum-phase fit.
    data : FrequencyData
    max_rel_error, rms_rel_error : float
        The fit's errors on ``data``.
    ratio, floor : float
        The free-zeros fit must reach ``ratio`` times the fit's RMS, and the fit's RMS must
        be at least ``floor``, for the record.

    Returns
    -------
    tuple of Diagnostic
    """
    if rms_rel_error < floor or model.n_sections == 0:
        return ()
    per = 2 if model.structure.basis == "second-order" else 1
    # at the fitted delay, and at none (a minimum-phase fit may have pushed its delay far
    # beyond the data's to mimic the excess phase)
    fits = [f for f in (_vf_free_zeros(data, model, per * model.n_sections),
                        _vf_free_zeros(data, model, per * model.n_sections, 0.0)
                        if model.delay > 0 else None) if f is not None]
    vf = min(fits, key=lambda f: f[1]) if fits else None
    source, k_free = "vector fitting", model.origin_order
    if vf is None or vf[2].size == 0 or not vf[1] < ratio * rms_rel_error:
        # vector fitting at a fixed delay misses the excess phase when the fit's delay is
        # far from the data's (a poor minimum-phase fit trades them): the rational start
        # with free zeros searches the delay itself
        found = _start_free_zeros(data, model, ratio * rms_rel_error)
        if found is None:
            return ()
        *vf, phase_min, k_free = found
        if not vf[1] < ratio * phase_min:
            return ()       # the minimum-phase start does as well: a poor fit, not the class
        source = "rational start"
    vmax, vrms, rhp = vf
    if rhp.size == 0 or not vrms < ratio * rms_rel_error:
        return ()
    values = {"n_rhp_zeros": int(rhp.size), "rhp_zeros": [[float(z.real), float(z.imag)]
                                                          for z in rhp],
              "free_zeros_max_rel_error": vmax, "free_zeros_rms_rel_error": vrms,
              "free_zeros_fit": source, "free_zeros_integrator": int(k_free),
              "max_rel_error": float(max_rel_error), "rms_rel_error": float(rms_rel_error)}
    msg = (f"excess phase a delay cannot explain: a stable model of the same order with "
           f"free zeros needs {rhp.size} right-half-plane zero(s) (|z| = {_freqs(rhp)} "
           f"{data.unit}) and reaches RMS relative error {vrms:.3g} (max {vmax:.3g}) against "
           f"{rms_rel_error:.3g} (max {max_rel_error:.3g}) for the minimum-phase fit; "
           "refit with zeros='free' (stable poles, zeros anywhere: the model is then not "
           "minimum phase) or accept the minimum-phase model's error")
    return (Diagnostic("non-minimum-phase", msg, "warning", values),)


def _start_free_zeros(data, model, limit):
    """``(max, rms relative error, right-half-plane zeros in the band, minimum-phase RMS,
    k)`` of the best rational start with free zeros on ``data`` (the model's structure with
    zeros="free", at its k and at k = 0, its gain sign first and the other when that start
    is not at :data:`EXACT_START`; zeros in the data's units, those far below the band
    left out), then the lowest RMS of the starts with minimum-phase zeros at those k
    and at every k of :data:`ORIGIN_ORDERS` (a minimum-phase model with roots at the
    origin that explains the data as well: not excess phase; run only when the free start
    has zeros in the band and an RMS below ``limit``, else inf) and the best start's k; None
    when no free-zeros start is usable."""
    from ..core.resolution import default_delay_max
    from ..core.scaling import reference_scales, scale_data
    from .start import memo_map

    w_ref, g_ref = reference_scales(data)
    scaled = scale_data(data, w_ref, g_ref)
    dmax = default_delay_max(scaled.omega)
    first = int(model.structure.gain_sign)

    def lowest(ks, zeros):
        """(RMS, max, zeros, k) of the best start over ``ks`` and both signs, or None (each
        k's starts independent: in workers where the fit allows them)."""
        found = memo_map(_signed_starts, [
            (scaled, dataclasses.replace(model.structure, integrator=k, zeros=zeros,
                                         gain_sign=1), first, dmax) for k in ks])
        best = None
        for k, one in zip(ks, found):
            if one is not None and (best is None or one[0] < best[0]):
                best = one + (k,)
        return best

    free_ks = tuple(dict.fromkeys((model.origin_order, 0)))
    best = lowest(free_ks, "free")
    if best is None:
        return None
    rms, worst, zeros, k_best = best
    # zeros far below the band stand for zeros at the origin, whichever their half plane
    rhp = zeros[(zeros.real > 0) & (np.abs(zeros) <= scaled.omega[-1])
                & (np.abs(zeros) >= BELOW_BAND * scaled.omega[0])]
    phase_min = math.inf
    if rhp.size and rms < limit:         # the minimum-phase starts only where it can count
        mp = lowest(tuple(dict.fromkeys(free_ks + ORIGIN_ORDERS)), "minimum-phase")
        phase_min = math.inf if mp is None else mp[0]
    return worst, rms, rhp * w_ref, phase_min, k_best


def _signed_starts(scaled, structure, first, delay_max):
    """(RMS, max, zeros) of the better of ``structure``'s rational starts on ``scaled``
    with the gain sign ``first`` and, unless that one is at :data:`EXACT_START`, the other
    (the first on a tie); None when neither is usable."""
    from .start import best_signed_start

    best = best_signed_start(scaled, structure, (first, -first), delay_max=delay_max,
                             exact=EXACT_START)
    return None if best is None else best[:2] + (best[2].model.zeros(),)


def rhp_zeros_note(model):
    """``non-minimum-phase`` "info" record for a model fitted with ``zeros="free"`` that
    has right-half-plane zeros (empty if it has none).

    Parameters
    ----------
    model : RationalDelayModel

    Returns
    -------
    tuple of Diagnostic
    """
    z = model.zeros()
    rhp = z[z.real > 0]
    if rhp.size == 0:
        return ()
    msg = (f"the model is not minimum phase (zeros='free'): {rhp.size} right-half-plane "
           f"zero(s), |z| = {_freqs(rhp)} rad/s; its poles are stable")
    return (Diagnostic("non-minimum-phase", msg, "info",
                       {"n_rhp_zeros": int(rhp.size),
                        "rhp_zeros": [[float(r.real), float(r.imag)] for r in rhp]}),)


def _low_gain(model, w_min):
    """``(w, |G(jw)|)`` at the lowest nonzero root of P_N below ``w_min``: the gain the
    model's roots below the band set there."""
    roots = np.concatenate([model.poles(), model.zeros()])
    roots = roots[(np.abs(roots) > 0) & (np.abs(roots) < w_min)]
    w = float(np.min(np.abs(roots))) if roots.size else w_min
    if roots.size and roots[np.argmin(np.abs(roots))].real == 0:
        w *= 0.5                    # an undamped root there (zeta = 0): below it
    return w, float(abs(model.frequency_response(np.array([w]))[0]))


def check_roots_below_band(model, data, fraction=BELOW_BAND):
    """``root-below-band`` records: poles / zeros of P_N with ``|r| < fraction * omega_min``
    (the integrator's pole, asked for, is not counted).

    Within the band such a pole acts as ``1/s`` (an integrator, with the gain it takes
    from its partner), such a zero as ``s``: the data ask for a model the fit's structure
    does not have; the fit keeps the root at its floor (``LoopOptions.root_floor``).

    Parameters
    ----------
    model : RationalDelayModel
    data : FrequencyData
    fraction : float
        Default :data:`BELOW_BAND`.

    Returns
    -------
    tuple of Diagnostic
    """
    if model.n_sections == 0:
        return ()
    w_min = float(data.omega[0])
    found = []
    k = model.origin_order
    for kind, roots, asked, stands in (
            ("pole", model.poles()[max(k, 0):], k + 1,
             f"an integrator (refit with integrator={spell_origin(k + 1)})" if k >= 0 else
             f"fewer zeros at the origin (refit with integrator={spell_origin(k + 1)})"),
            ("zero", model.zeros()[max(-k, 0):], k - 1,
             f"a differentiator (a zero at 0; refit with integrator={spell_origin(k - 1)})")):
        low = roots[np.abs(roots) < fraction * w_min]
        if low.size == 0:
            continue
        if abs(asked) > MAX_ORIGIN_ORDER:       # no such model: say what is left to do
            stands = (f"{abs(asked)} {'poles' if asked > 0 else 'zeros'} at the origin, more "
                      f"than a model may have ({MAX_ORIGIN_ORDER}): the data fall or rise "
                      "faster at their low end than the model class follows; fit them from "
                      "a higher lowest frequency (band=), or check the low-frequency points")
        fu = data.unit
        values = {"kind": kind, "roots": [[float(r.real), float(r.imag)] for r in low],
                  "omega_min": w_min, "fraction": float(fraction),
                  "integrator_asked": int(asked)}
        others = model.zeros()[max(-k, 0):] if kind == "pole" else model.poles()[max(k, 0):]
        partners = others[np.abs(others) < w_min]
        if not partners.size:
            msg = (f"{low.size} {kind}(s) at |r| = {_freqs(low)} {fu}, far "
                   f"below the lowest data frequency {w_min:.4g} {fu}: the data cannot tell "
                   f"them from 0 and ask for {stands}")
        else:
            # the actuator at 2 sections: a pole at 2.4e-7 with a zero at 0.05 rad/s, the
            # band from 0.77: a lag-lead step at the band's edge, G(0) = 2.1e5 for |G| = 1
            w0, g0 = _low_gain(model, w_min)
            other = "zero" if kind == "pole" else "pole"
            msg = (f"{low.size} {kind}(s) at |r| = {_freqs(low)} {fu}, far below the lowest "
                   f"data frequency {w_min:.4g} {fu}, with {other}(s) below it too (|r| = "
                   f"{_freqs(partners)} {fu}): in the band they act together as a step at its "
                   "low edge; below it, they set the model's low-frequency gain "
                   f"(|G| = {g0:.3g} at {w0:.4g} {fu}, "
                   f"against {abs(data.response[0]):.3g} at the lowest data frequency), "
                   "which the data do not determine: if you know the static gain, hold it "
                   "(fixed={'dc_gain': K}); an integrator (integrator=True) only if the "
                   "system integrates; else fit the band from a higher lowest frequency")
            values["partner_roots"] = [[float(r.real), float(r.imag)] for r in partners]
        found.append(Diagnostic("root-below-band", msg, "warning", values))
    return tuple(found)

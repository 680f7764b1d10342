"""How well the data determine a fitted model: parameter covariance, bands, bootstrap (L4).

The fit minimises ``sum_i w_i |r_i|^2`` over the relative residuals
``r_i = Phi_i / G_N(j w_i) - 1`` (stacked as 2M real numbers). Near the optimum the
estimate is linear in the noise (delta method), so with ``J = d[Re r; Im r]/d theta`` in
the physical parameters of :mod:`freqid_casadi.core.physical` (delay, log gain, natural
frequency and damping of every quadratic factor, root of every first-order one)::

    Cov(theta) = sigma^2 (J^T W J)^-1                       noise from the residuals
    sigma^2    = sum_i w_i |r_i|^2 / (2 M - p)              (per real component)
    Cov(theta) = (J^T W J)^-1 J^T W S W J (J^T W J)^-1      noise variance S given

(``S`` the variance of each real component of ``r``: ``E|Phi - G|^2 / (2 |G_N|^2)``; with
``W = S^-1`` the sandwich is ``(J^T W J)^-1``). Without a given variance, when the
residuals' level changes over the band (:func:`local_variance`: Bartlett's test over
blocks of frequency) ``S`` is their local level (``heteroscedastic`` True).
Parameters at a bound (a damping of 0 or at the fit's floor, a delay of 0, a missing
coefficient) are excluded from the inversion and
reported with ``at_bound`` True and a NaN standard deviation: the data do not make them
known exactly, the bound does. The derivatives of ``ln G_N`` are analytic; the columns are
scaled to unit norm before the inversion (an SVD, whose condition number is reported).

:func:`bootstrap` gives the same record from a residual bootstrap (joblib-parallel);
:mod:`freqid_casadi.uncertainty.bands` the delta-method band of the response and of the
relative error.
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..core import physical as _physical
from ..core.data import FrequencyData
from ..errors import DataError, OptionError, StructureError
from ..core.model import RationalDelayModel
from .bias import with_unbiased_gain
from .determined import determined_status

__all__ = ["ModeEstimate", "ParameterUncertainty", "parameter_uncertainty", "held_parameters",
           "with_std", "with_status", "NOISE_SOURCES"]

#: Values of ``ParameterUncertainty.noise_source``.
NOISE_SOURCES = ("residuals", "given", "data", "bootstrap")
#: Level of the test for a noise level that changes over the band (:func:`local_variance`).
HETEROSCEDASTIC_P = 0.01


def z_quantile(level, dist="normal", dof=None):
    """Two-sided quantile of the normal (or Student t with ``dof``) distribution."""
    if not (isinstance(level, (int, float)) and 0 < level < 1):
        raise OptionError(f"level must be in (0, 1), got {level!r}; e.g. 0.95")
    from scipy import stats

    q = 0.5 + level / 2
    if dist == "normal":
        return float(stats.norm.ppf(q))
    if dist == "t":
        return float(stats.t.ppf(q, max(int(dof or 1), 1)))
    raise OptionError(f"unknown dist {dist!r}; choose 'normal' or 't'")


@dataclass(frozen=True)
class ModeEstimate:
    """Natural frequency and damping of one lightly damped pole pair, with their spread.

    Attributes
    ----------
    section : int
        Section (1-based) of the model whose denominator holds the pole pair.
    omega_n, omega_n_std : float
        Natural frequency and its standard deviation, rad/s.
    frequency_hz, frequency_hz_std : float
        The same in Hz.
    zeta, zeta_std : float
        Damping ratio (< 1) and its standard deviation; ``zeta_std`` is NaN when the
        damping is at its bound (``zeta_at_bound``).
    zeta_at_bound : bool
    omega_n_determined, zeta_determined : bool
        False when the interval of ``omega_n`` (``zeta``) is not to be trusted (see
        :mod:`freqid_casadi.uncertainty.determined`); the std keeps its value.
    reason : str
        Why not ("" when both are determined).
    """

    section: int
    omega_n: float
    omega_n_std: float
    frequency_hz: float
    frequency_hz_std: float
    zeta: float
    zeta_std: float
    zeta_at_bound: bool = False
    omega_n_determined: bool = True
    zeta_determined: bool = True
    reason: str = ""

    def interval(self, level=0.95):
        """Normal confidence intervals ``{"omega_n": (lo, hi), "zeta": (lo, hi)}``."""
        z = z_quantile(level)
        return {"omega_n": (self.omega_n - z * self.omega_n_std,
                            self.omega_n + z * self.omega_n_std),
                "zeta": (self.zeta - z * self.zeta_std, self.zeta + z * self.zeta_std)}


@dataclass(frozen=True, eq=False)
class ParameterUncertainty:
    """Covariance of a fitted model's physical parameters and what follows from it.

    Attributes
    ----------
    model : RationalDelayModel
        The model it describes.
    param_names : tuple of str, length P
        See :mod:`freqid_casadi.core.physical` (``delay``, ``log_gain``, ``omega_den[k]``,
        ``zeta_den[k]``, ``omega_num[k]``, ...).
    values : ndarray of float, shape (P,)
        The parameter values (s, ln gain, rad/s, 1); delta method: ``ln gain`` corrected
        for the relative criterion's bias (:mod:`freqid_casadi.uncertainty.bias`).
    at_bound : ndarray of bool, shape (P,)
        Parameters at a bound, excluded from the inversion.
    covariance : ndarray of float, shape (P, P)
        NaN in the rows and columns of parameters at a bound.
    std : ndarray of float, shape (P,)
        Square root of the diagonal (NaN at a bound).
    delay, delay_std : float
        Delay and its standard deviation, s (NaN std without a delay or at its bound).
    gain, gain_std : float
        Gain ``g`` (lowest coefficient of ``K s^(-k) P_N``: DC gain, K0 with poles at 0;
        signed; delta method: the model's times ``1 - ms``, corrected for the relative
        criterion's bias, :mod:`freqid_casadi.uncertainty.bias`) and its standard
        deviation ``g * std(log_gain)``.
    modes : tuple of ModeEstimate
        Every denominator quadratic with ``zeta < 1``, by increasing ``omega_n``.
    noise_source : str
        "residuals" (``sigma2`` estimated from the weighted residuals), "given" (the
        ``noise_variance`` argument), "data" (``FrfEstimate.variance``) or "bootstrap"
        (empirical covariance of refits).
    sigma2 : float
        ``sum w_i |r_i|^2 / (2 M - p)``: the residual variance per real component (always
        computed; the covariance uses it when ``noise_source == "residuals"``).
    dof : int
        Degrees of freedom ``2 M - p`` (points with nonzero weight, free parameters).
    condition_number : float
        Of the column-scaled weighted Jacobian (large: parameters nearly redundant).
    method : str
        "delta" or "bootstrap".
    samples : ndarray of float, shape (n_boot, P) or None
        Bootstrap only: the refitted parameters (NaN rows for failed refits).
    response_factor : ndarray of float, shape (P, K) or None
        Delta method only: ``F`` with ``F F^T`` = ``covariance`` without the directions
        the data do not determine at all (numerically zero singular values of the
        Jacobian, along which the response does not move); NaN rows at a bound.
        :func:`~freqid_casadi.uncertainty.bands.response_band` sums squares ``|g F|^2`` (never
        negative, no cancellation), see :attr:`response_covariance`.
    fixed : tuple of str
        Parameters the fit held at known values (``fit(..., fixed=...)``: ``delay``,
        ``log_gain``): not estimated, so ``at_bound`` True and a NaN standard deviation.
    determined : ndarray of bool, shape (P,) or None
        Delta method only: False where the parameter's interval is not to be trusted
        (at a bound, a singular direction, an interval reaching 0, a factor outside the
        band or a parameter trading with one; see
        :mod:`freqid_casadi.uncertainty.determined`). ``std`` keeps its value there.
    reasons : tuple of str, length P
        Why each parameter is not determined ("" where it is).
    heteroscedastic : bool
        With the noise from the residuals: True when their level changes over the band
        (Bartlett's test over blocks of frequency, p < 0.01) and the covariance is the
        sandwich with their local level (:func:`local_variance`) instead of one
        ``sigma2`` (measured: a noise 5.5 times larger at the top of the band than at its
        bottom, unweighted, gave delay intervals covering 70 % with one level).
    """

    model: RationalDelayModel
    param_names: tuple
    values: np.ndarray
    at_bound: np.ndarray
    covariance: np.ndarray
    std: np.ndarray
    delay: float
    delay_std: float
    gain: float
    gain_std: float
    modes: tuple
    noise_source: str
    sigma2: float
    dof: int
    condition_number: float
    method: str = "delta"
    samples: np.ndarray = None
    response_factor: np.ndarray = None
    fixed: tuple = ()
    determined: np.ndarray = None
    reasons: tuple = ()
    heteroscedastic: bool = False

    @property
    def not_determined(self):
        """``{name: reason}`` of the parameters whose interval is not to be trusted
        (empty without :attr:`determined`)."""
        if self.determined is None:
            return {}
        return {n: r for n, d, r in zip(self.param_names, self.determined, self.reasons)
                if not d}

    def is_determined(self, name):
        """True when the interval of ``name`` can be trusted (see :attr:`determined`);
        True for every parameter of a record without the status (bootstrap)."""
        i = self._index(name)
        return True if self.determined is None else bool(self.determined[i])

    @property
    def response_covariance(self):
        """``response_factor @ response_factor.T`` (P, P), or None."""
        f = self.response_factor
        return None if f is None else f @ f.T

    def std_of(self, name):
        """Standard deviation of the parameter ``name`` (NaN at a bound)."""
        return float(self.std[self._index(name)])

    def _index(self, name):
        try:
            return self.param_names.index(name)
        except ValueError:
            raise OptionError(f"unknown parameter {name!r}; choose one of "
                              f"{', '.join(self.param_names)}") from None

    def interval(self, name, level=0.95, dist="normal"):
        """Confidence interval ``(lo, hi)`` of one parameter.

        Parameters
        ----------
        name : str
            One of :attr:`param_names`.
        level : float
            Confidence level in (0, 1).
        dist : {"normal", "t"}
            Normal quantile, or Student t with :attr:`dof` degrees of freedom.
        """
        i = self._index(name)
        z = z_quantile(level, dist, self.dof)
        return (float(self.values[i] - z * self.std[i]), float(self.values[i] + z * self.std[i]))

    def to_dict(self):
        """JSON-ready dict: names, values, at_bound, covariance (NaN as None), noise info."""
        def clean(a):
            return [None if not np.isfinite(v) else float(v) for v in np.ravel(a)]

        p = len(self.param_names)
        return {"method": self.method, "noise_source": self.noise_source,
                "sigma2": self.sigma2, "dof": self.dof, "param_names": list(self.param_names),
                "values": clean(self.values), "at_bound": [bool(b) for b in self.at_bound],
                "covariance": [clean(self.covariance[i]) for i in range(p)],
                "delay_std": clean([self.delay_std])[0], "gain": self.gain,
                "fixed": list(self.fixed),
                "not_determined": self.not_determined,
                "heteroscedastic": bool(self.heteroscedastic),
                "gain_std": clean([self.gain_std])[0]}

    def intervals(self, level=0.95, dist="normal"):
        """``{name: (lo, hi)}`` for every parameter (NaN bounds at a bound)."""
        return {n: self.interval(n, level, dist) for n in self.param_names}


# --------------------------------------------------------------------------- inputs

def held_parameters(result):
    """Names of the physical parameters a fit held at known values.

    Parameters
    ----------
    result : FitResult or RationalDelayModel
        Its ``fixed`` ("delay" -> ``delay``, "dc_gain" -> ``log_gain``); none for a model.

    Returns
    -------
    tuple of str
    """
    fixed = getattr(result, "fixed", None) or {}
    return tuple(name for key, name in (("delay", "delay"), ("dc_gain", "log_gain"))
                 if key in fixed)


def covariance_inputs(model, data, weights, noise_variance, bound_tol):
    """Model, FrequencyData, weights (M,), absolute noise variance or None, source, par."""
    zeta_floor, delay_max, source, variance = 0.0, None, "residuals", None
    held = held_parameters(model)
    if hasattr(model, "model") and hasattr(model, "rel_error"):          # a FitResult
        opts = model.options_dict() if hasattr(model, "options_dict") else {}
        zeta_floor = float(opts.get("min_damping") or 0.0)
        delay_max = opts.get("delay_max") if opts.get("bound_delay", True) else None
        data = model.data if data is None else data
        model = model.model
    if not isinstance(model, RationalDelayModel):
        raise StructureError(f"model must be a RationalDelayModel or FitResult, got "
                             f"{type(model).__name__}")
    if hasattr(data, "data") and hasattr(data, "variance"):              # an FrfEstimate
        variance, data = data.variance, data.data
        source = "data" if variance is not None else source
    if not isinstance(data, FrequencyData):
        raise DataError(f"data must be a FrequencyData or FrfEstimate, got "
                        f"{type(data).__name__}; pass the data the model was fitted to")
    m = data.n_points
    w = weights if weights is not None else data.weights
    w = np.ones(m) if w is None else data.with_weights(w).weights
    if noise_variance is not None:
        variance, source = noise_variance, "given"
    if variance is not None:
        variance = np.broadcast_to(np.asarray(variance, dtype=float), (m,)).copy()
        if not np.all(np.isfinite(variance) & (variance > 0)):
            raise DataError("noise_variance must be finite and > 0 (E|Phi - G|^2 per point, "
                            "scalar or shape (M,))")
    par = _physical.parametrize(model, float(data.omega[-1]), zeta_floor=zeta_floor,
                                delay_max=delay_max, bound_tol=bound_tol)
    if held:                      # known parameters: out of the inversion, like a bound
        at = np.array(par.at_bound)
        at[[par.names.index(n) for n in held]] = True
        at.setflags(write=False)
        par = dataclasses.replace(par, at_bound=at)
    return model, data, np.asarray(w, dtype=float), variance, source, par


def residual_jacobian(par, theta, data):
    """Relative residual r (M,) complex and its Jacobian d r / d theta (M, P) complex."""
    log_g, d_log_g = _physical.log_response(par, theta, data.omega)
    ratio = data.response * np.exp(-log_g)
    return ratio - 1.0, -ratio[:, None] * d_log_g


def _stack(z):
    return np.concatenate([z.real, z.imag], axis=0)


def _inverse(a):
    """(A^T A)^-1 and a factor ``F`` (p, k) of its pseudo-inverse over the determined
    directions (``F F^T``), via the SVD of A (2M, p) with unit-norm columns; and the
    condition.

    The determined directions are those whose singular value exceeds ``eps * max(2M, p)``
    of the largest (numpy.linalg.lstsq's cutoff). Below it a direction is numerically
    null (e.g. an exactly cancelling pole/zero pair, or a zero at infinity against the
    delay): the parameters' variances keep it (huge: the data do not determine them), the
    response's leave it out (the response does not move along it; inverted, rounding
    times 1e32 made example C's response band 1e6 times wider than ``sigma^2 *
    leverage``, its bound at the data frequencies).
    """
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    _, sv, vt = np.linalg.svd(a / scale, full_matrices=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    inv_s = (vt.T / np.where(sv > 0, sv, np.nan) ** 2) @ vt
    keep = sv > np.finfo(float).eps * max(a.shape) * sv[0]
    factor = vt[keep].T / sv[keep] / scale[:, None]       # (p, k): det = F F^T
    return inv_s / np.outer(scale, scale), factor, cond


def _covariance(r, jac, w, variance, g_abs2, free):
    """Free-parameter covariance (p, p), a factor (p, k) of its part over the determined
    directions, sigma2, dof, condition (see module notes and :func:`_inverse`)."""
    sw = np.sqrt(np.concatenate([w, w]))
    a = sw[:, None] * _stack(jac[:, free])
    n_obs = 2 * int(np.count_nonzero(w > 0))
    dof = n_obs - int(np.count_nonzero(free))
    if dof <= 0:
        raise DataError(f"{n_obs // 2} weighted points cannot determine "
                        f"{int(np.count_nonzero(free))} parameters; use more data")
    sigma2 = float(np.sum(w * np.abs(r) ** 2) / dof)
    inv, factor, cond = _inverse(a)
    if variance is None:
        return sigma2 * inv, np.sqrt(sigma2) * factor, sigma2, dof, cond
    s = np.concatenate([variance, variance]) / (2 * np.concatenate([g_abs2, g_abs2]))
    # det meat det = (det A^T sqrt(D)) (...)^T, det = F F^T
    sandwich = factor @ ((a @ factor).T * np.sqrt(s) * sw)
    return _sandwich(a, np.sqrt(s) * sw), sandwich, sigma2, dof, cond


def _sandwich(a, root_d):
    """``(A^T A)^-1 A^T D A (A^T A)^-1`` as ``B B^T`` with ``B = (A^T A)^-1 A^T sqrt(D)``
    from the SVD of the column-scaled A (never negative on the diagonal, unlike the
    product of the three matrices when A is nearly singular)."""
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    u, sv, vt = np.linalg.svd(a / scale, full_matrices=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = ((vt.T / np.where(sv > 0, sv, np.nan)) @ (u.T * root_d)) / scale[:, None]
    return b @ b.T


def covariance_record(model, par, cov_free, free, sigma2, dof, cond, source, method, samples=None,
            factor_free=None):
    """Assemble a ParameterUncertainty from the free-parameter covariance (and the factor
    of its part over the determined directions, ``response_factor``)."""
    p = par.n_params
    cov = np.full((p, p), np.nan)
    cov[np.ix_(free, free)] = cov_free
    resp = None
    if factor_free is not None:
        resp = np.full((p, factor_free.shape[1]), np.nan)
        resp[free] = factor_free
        resp.setflags(write=False)
    std = np.sqrt(np.where(np.diag(cov) >= 0, np.diag(cov), np.nan))
    values = np.array(par.theta)
    modes = []
    for f in par.factors:
        if f.sign < 0 and f.kind == _physical.QUADRATIC and values[f.slots[1]] < 1:
            iw, iz = f.slots
            modes.append(ModeEstimate(
                section=f.section, omega_n=float(values[iw]), omega_n_std=float(std[iw]),
                frequency_hz=float(values[iw] / (2 * np.pi)),
                frequency_hz_std=float(std[iw] / (2 * np.pi)), zeta=float(values[iz]),
                zeta_std=float(std[iz]), zeta_at_bound=bool(par.at_bound[iz])))
    modes.sort(key=lambda m: m.omega_n)
    ig = par.index("log_gain")
    gain = float(model.structure.gain_sign * np.exp(values[ig]))   # signed, like model.gain
    delay_std = float(std[0]) if par.structure.delay else math.nan
    for arr in (values, cov, std):
        arr.setflags(write=False)
    return ParameterUncertainty(
        model=model, param_names=par.names, values=values, at_bound=np.array(par.at_bound),
        covariance=cov, std=std, delay=model.delay, delay_std=delay_std, gain=gain,
        gain_std=float(abs(gain) * std[ig]), modes=tuple(modes), noise_source=source,
        sigma2=float(sigma2), dof=int(dof), condition_number=float(cond), method=method,
        samples=samples, response_factor=resp)


def parameter_uncertainty(model, data=None, *, weights=None, noise_variance=None,
                          bound_tol=1e-8, noise_level="auto"):
    """Delta-method covariance of a fitted model's physical parameters.

    Parameters
    ----------
    model : RationalDelayModel or FitResult
        The fitted model; a FitResult also gives the data, its weights and the fit's
        bounds (damping floor ``min_damping``, ``delay_max``).
    data : FrequencyData or FrfEstimate, optional
        The data the model was fitted to (M points); an FrfEstimate with ``variance``
        supplies the noise variance. Required with a bare model.
    weights : array_like of float, shape (M,), optional
        The fit's weights of the squared relative residuals (default ``data.weights`` or 1).
    noise_variance : float or array_like of float, shape (M,), optional
        Variance ``E|Phi_i - G(j w_i)|^2`` of the complex data (response units squared);
        overrides the data's. Without any, it is estimated from the residuals.
    bound_tol : float
        Relative tolerance for a parameter to count as at its bound.
    noise_level : {"auto", "constant", "local"}
        With the noise from the residuals: "constant" one ``sigma2`` for every point;
        "local" the residuals' local level when it changes over the band
        (:func:`local_variance`); "auto" (default) "local" for a FitResult whose status
        is "ok" (its residual is noise), else "constant" (a bare model's residual may be
        model error).

    Returns
    -------
    ParameterUncertainty
        ``noise_source`` says where the noise level came from; ``heteroscedastic``
        whether the local level was used; ``determined`` / ``reasons`` which intervals
        to trust.

    Raises
    ------
    DataError
        Data of the wrong type, bad weights or variance, fewer observations than
        parameters.
    StructureError
        Not a model, or a section with a zero numerator or denominator.

    Notes
    -----
    See the module notes for the formulas. The delta method is first order: it is
    accurate when the standard deviations are small against the parameters (a damping
    known to 30 % of itself or a mode narrower than the frequency spacing are beyond it;
    compare with :func:`bootstrap`).
    """
    from .._threads import single_threaded_blas

    # one BLAS thread, as in fit(): the SVDs are of a (2M, p) matrix, and OpenBLAS threads
    # on a shared machine made them 5-40x slower (A at 17 sections: 0.33-2.7 s against
    # 0.07 s); the numbers then do not depend on the thread count either
    with single_threaded_blas():
        return _parameter_uncertainty(model, data, weights, noise_variance, bound_tol,
                                      noise_level)


def _parameter_uncertainty(model, data, weights, noise_variance, bound_tol, noise_level):
    fit_result = model
    if noise_level not in ("auto", "constant", "local"):
        raise OptionError(f"noise_level must be 'auto', 'constant' or 'local', got "
                          f"{noise_level!r}")
    status = getattr(fit_result, "status", None)
    status = getattr(status, "value", status)           # FitStatus -> its string
    local = noise_level == "local" or (noise_level == "auto" and status == "ok")
    model, data, w, variance, source, par = covariance_inputs(model, data, weights, noise_variance,
                                                    bound_tol)
    r, jac = residual_jacobian(par, par.theta, data)
    free = ~par.at_bound
    g_abs2 = np.abs(data.response / (1 + r)) ** 2
    hetero = False
    if variance is None and local:
        variance = local_variance(r, w, g_abs2, int(np.count_nonzero(free)))
        hetero = variance is not None
    cov, factor, sigma2, dof, cond = _covariance(r, jac, w, variance, g_abs2, free)
    held = held_parameters(fit_result)
    rec = covariance_record(model, par, cov, free, sigma2, dof, cond, source, "delta",
                            factor_free=factor)
    rec = dataclasses.replace(rec, fixed=held, heteroscedastic=hetero)
    rec = with_unbiased_gain(rec, r, w)       # the relative criterion's 1 + sigma^2 (bias.py)
    return with_status(rec, par, data.omega, data.unit, status)


def local_variance(r, w, g_abs2, n_free, p_value=HETEROSCEDASTIC_P):
    """The residuals' local noise level when it changes over the band, else None.

    The weighted residuals ``sqrt(w_i) r_i`` are split into contiguous blocks of
    frequency (up to 8, at least 25 points each); when Bartlett's test rejects one
    variance for all blocks at ``p_value``, the local level is the local-linear smooth of
    ``w_i |r_i|^2`` over a window of ``max(11, M / blocks)`` points (:func:`_local_linear`;
    corrected by ``2M / (2M - p)`` like ``sigma2``).

    Parameters
    ----------
    r : ndarray of complex, shape (M,)
        Relative residuals.
    w : ndarray of float, shape (M,)
        Weights.
    g_abs2 : ndarray of float, shape (M,)
        ``|G_N(j w_i)|^2``.
    n_free : int
        Free parameters.
    p_value : float
        Level of the test.

    Returns
    -------
    ndarray of float, shape (M,) or None
        The absolute noise variance ``E|Phi_i - G_i|^2`` per point (the ``noise_variance``
        the sandwich takes), None when one level fits (or fewer than 50 weighted points).
    """
    on = np.flatnonzero(w > 0)
    m = on.size
    n_blocks = min(8, m // 25)
    if n_blocks < 2:
        return None
    x = np.sqrt(w[on]) * r[on]
    blocks = [np.concatenate([b.real, b.imag]) for b in np.array_split(x, n_blocks)]
    if not _bartlett_pvalue(blocks) < p_value:
        return None
    k = max(11, m // n_blocks) | 1
    level = _local_linear(np.abs(x) ** 2, k)
    level *= 2 * m / max(2 * m - n_free, 1)
    variance = np.ones(r.size)
    variance[on] = level / w[on] * g_abs2[on]
    return variance


def _local_linear(y, k):
    """Local-linear smooth of ``y`` (M,) over centred windows of ``k`` (odd) entries,
    shrunk at the ends: at each point the value at that point of the least-squares line
    through the window, kept at least a quarter of the window's mean.

    A running mean is biased where the level slopes and the window is cut by the band's
    end: for noise rising 5.5 times over 50 points it put the top of the band about 18 %
    low, where a delay's information sits (its intervals covered 89.5 % of 400
    replicates; with the true variance 94.3 %, with this smooth 92.5 %). The line has no
    such bias; the floor keeps a line fitted to a few chi-square values off zero at an
    end.
    """
    m = y.size
    h = (min(k, m) - 1) // 2                    # the window fits in the data
    ones, d = np.ones(2 * h + 1), np.arange(-h, h + 1, dtype=float)

    def window_sum(v, kernel):                  # sum over j in the window of kernel(j - i) v_j
        return np.convolve(v, kernel[::-1], mode="same")
    s0, s1, s2 = (window_sum(np.ones(m), kern) for kern in (ones, d, d * d))
    t0, t1 = window_sum(y, ones), window_sum(y, d)
    line = (s2 * t0 - s1 * t1) / (s0 * s2 - s1 * s1)
    return np.maximum(line, 0.25 * t0 / s0)


def _bartlett_pvalue(samples):
    """p-value of Bartlett's test that the samples (a list of 1-D float arrays, at least
    two of at least two values each) have one variance: scipy.stats.bartlett's statistic
    and chi-square tail, written out (importing scipy.stats took 0.3-3 s, once per
    process, the largest part of a first ``FitResult.uncertainty``)."""
    from scipy.special import chdtrc

    k = len(samples)
    ni = np.array([s.size for s in samples], dtype=float)
    ssq = np.array([np.var(s, ddof=1) for s in samples])
    ntot = np.sum(ni)
    spsq = np.sum((ni - 1) * ssq) / (ntot - k)
    numer = (ntot - k) * np.log(spsq) - np.sum((ni - 1) * np.log(ssq))
    denom = 1 + 1 / (3 * (k - 1)) * (np.sum(1 / (ni - 1)) - 1 / (ntot - k))
    return float(chdtrc(k - 1, numer / denom))


def with_status(rec, par, omega, unit="rad/s", fit_status=None):
    """``rec`` with :attr:`ParameterUncertainty.determined` and ``reasons`` filled (and its
    modes' ``omega_n_determined``, ``zeta_determined``, ``reason``), see
    :func:`freqid_casadi.uncertainty.determined.determined_status`.

    Parameters
    ----------
    rec : ParameterUncertainty
    par : freqid_casadi.core.physical.Parametrization
        The parametrisation ``rec`` was computed in.
    omega : ndarray of float, shape (M,)
        The data frequencies, rad/s (the band).
    unit : str
        Frequency unit named in the reasons.
    fit_status : str, optional
        ``FitResult.status`` of the fit: other than "ok" (a "poor-fit" or
        "not-converged" fit), no parameter is determined.

    Returns
    -------
    ParameterUncertainty
    """
    det, reasons = determined_status(par, rec.values, rec.covariance, rec.std, omega, unit,
                                     fit_status)
    slot = {}
    for f in par.factors:
        if f.sign < 0 and f.kind == _physical.QUADRATIC:
            slot[f.section] = f.slots
    modes = []
    for m in rec.modes:
        iw, iz = slot[m.section]
        why = "; ".join(dict.fromkeys(r for r in (reasons[iw], reasons[iz]) if r))
        modes.append(dataclasses.replace(m, omega_n_determined=bool(det[iw]),
                                         zeta_determined=bool(det[iz]), reason=why))
    return dataclasses.replace(rec, determined=det, reasons=reasons, modes=tuple(modes))



def with_std(modes, unc, rtol=1e-6):
    """Copies of modal records with ``omega_n_std`` and ``zeta_std`` filled from ``unc``.

    Parameters
    ----------
    modes : sequence of frozen dataclasses
        Records with fields ``omega_n`` (rad/s), ``zeta``, ``omega_n_std`` and ``zeta_std``
        (e.g. ``freqid_casadi.core.modes.Mode``) of the model ``unc`` describes.
    unc : ParameterUncertainty
    rtol : float
        Relative tolerance of the match of ``omega_n`` with a mode of ``unc``.

    Returns
    -------
    list
        ``dataclasses.replace`` of each record; records without a matching pole pair
        (e.g. overdamped) keep their values.
    """
    import dataclasses

    out = []
    for rec in modes:
        match = [m for m in unc.modes if abs(m.omega_n - rec.omega_n) <= rtol * m.omega_n
                 and abs(m.zeta - rec.zeta) <= max(rtol, 1e-9)]
        out.append(dataclasses.replace(rec, omega_n_std=match[0].omega_n_std,
                                       zeta_std=match[0].zeta_std) if match else rec)
    return out

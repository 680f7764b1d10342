"""Confidence bands on the Bode and relative-error figures; the modal table with ± (L5).

matplotlib is imported inside the functions (``import freqid_casadi.plots.uncertainty``
does not load it). Every figure function returns a ``matplotlib.figure.Figure`` and never
calls ``show()``; write it with :func:`freqid_casadi.plots.save_figure`.
"""

import math

import numpy as np

from ..uncertainty.bands import response_band
from ..uncertainty.covariance import ParameterUncertainty, z_quantile
from ..core.data import FrequencyData
from ..errors import OptionError
from ._base import _dense_grid, _pyplot   # plots.bode's grid; lazy pyplot

__all__ = ["bode_band", "rel_error_band", "render_markdown"]


def _check(unc, data):
    if not isinstance(unc, ParameterUncertainty):
        raise OptionError(f"expected a ParameterUncertainty, got {type(unc).__name__}")
    if data is not None and not isinstance(data, FrequencyData):
        raise OptionError(f"data must be a FrequencyData, got {type(data).__name__}")


def bode_band(unc, data=None, *, omega=None, level=0.95, fig=None, title=None):
    """Bode plot with the model's confidence band (magnitude in dB, phase in degrees).

    Parameters
    ----------
    unc : ParameterUncertainty
    data : FrequencyData, optional
        Data drawn as markers (with :func:`freqid_casadi.plots.bode`) when ``fig`` is None.
    omega : array_like of float, shape (M,), optional
        Frequencies of the band, rad/s (default: 2000 log-spaced points over the data,
        merged with the data frequencies, the grid of ``plots.bode``).
    level : float
        Confidence level in (0, 1).
    fig : matplotlib.figure.Figure, optional
        A figure from :func:`freqid_casadi.plots.bode` of the same model: the band is added
        to its two axes. Default: a new one.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    _check(unc, data)
    if omega is None:
        if data is None:
            raise OptionError("bode_band needs data or omega: the frequencies of the band")
        omega = _dense_grid(data.omega)
    band = response_band(unc, np.asarray(omega, dtype=float), level=level)
    if fig is None:
        from .. import plots

        if data is not None:
            fig = plots.bode(data, models={"model": unc.model}, title=title)
        else:
            fig, axes = _pyplot().subplots(2, 1, sharex=True, layout="constrained")
            axes[0].semilogx(band.omega, 20 * np.log10(band.magnitude), "C1-", label="model")
            axes[1].semilogx(band.omega, np.rad2deg(band.phase), "C1-")
            axes[0].set_ylabel("magnitude (dB)")
            axes[1].set_ylabel("phase (degrees)")
            axes[1].set_xlabel(r"frequency $\omega$ (rad/s)")
    ax_mag, ax_ph = fig.axes[0], fig.axes[1]
    half_db = 20 * np.log10(band.magnitude_upper / band.magnitude)
    half_deg = np.rad2deg(band.phase_upper - band.phase)
    # the band is often thinner than the line: its largest half-width goes in the label
    label = (f"{100 * level:g} % band ({unc.method}), max ±{np.max(half_db):.2g} dB, "
             f"±{np.max(half_deg):.2g}°")
    lower_db, upper_db = (20 * np.log10(band.magnitude_lower),
                          20 * np.log10(band.magnitude_upper))
    lower_deg, upper_deg = np.rad2deg(band.phase_lower), np.rad2deg(band.phase_upper)
    # the axes keep the data's and the model's range: a band that is not determined
    # (thousands of dB where a pole is undamped) would flatten the curves to a line
    clipped = [_within(ax, lo, hi) for ax, lo, hi in ((ax_mag, lower_db, upper_db),
                                                      (ax_ph, lower_deg, upper_deg))]
    if any(clipped):
        label += " (beyond the axes in places)"
    ax_mag.fill_between(band.omega, lower_db, upper_db, color="C1", alpha=0.3, lw=0,
                        label=label)
    ax_ph.fill_between(band.omega, lower_deg, upper_deg, color="C1", alpha=0.3, lw=0)
    ax_mag.legend(loc="best", fontsize="small", framealpha=0.9)
    if title is not None:
        fig.suptitle(title)
    return fig


#: How far beyond the curves' own range (a share of its span, each side) a band may widen
#: the axes before it is cut off at the axes' edge.
BAND_MARGIN = 0.25


def _within(ax, lower, upper):
    """Set ``ax``'s y-limits to its curves' range widened to the band ``lower``..``upper``
    by at most :data:`BAND_MARGIN` of that span each side; True when the band is cut."""
    lo, hi = ax.get_ylim()
    span = hi - lo
    finite_lo, finite_hi = lower[np.isfinite(lower)], upper[np.isfinite(upper)]
    want_lo = min(lo, finite_lo.min()) if finite_lo.size else lo
    want_hi = max(hi, finite_hi.max()) if finite_hi.size else hi
    new_lo, new_hi = max(want_lo, lo - BAND_MARGIN * span), min(want_hi, hi + BAND_MARGIN * span)
    ax.set_ylim(new_lo, new_hi)
    return bool(want_lo < new_lo or want_hi > new_hi or finite_lo.size < lower.size
                or finite_hi.size < upper.size)


def rel_error_band(unc, data, *, level=0.95, fig=None, title=None):
    """Relative error ``|Phi/G_N - 1|`` with its band and the model's relative spread.

    Parameters
    ----------
    unc : ParameterUncertainty
    data : FrequencyData
        The data of the fit.
    level : float
        Confidence level in (0, 1); ``z`` its normal quantile.
    fig : matplotlib.figure.Figure, optional
        A figure with one log-log axes (e.g. from :func:`freqid_casadi.plots.
        relative_error`) to draw into; default a new one.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
        The error ``e`` (line), its upper band ``e + z std(e)`` (shaded; the edge an
        uncertainty weight must cover, :func:`freqid_casadi.uncertainty.bands.fit_band_weight`) and
        ``z rel_std`` (dashed: the model's own relative uncertainty).
    """
    _check(unc, data)
    if data is None:
        raise OptionError("rel_error_band needs the data the model was fitted to")
    band = response_band(unc, data=data, level=level)
    z = z_quantile(level)
    if fig is None:
        fig, ax = _pyplot().subplots(layout="constrained")
        ax.loglog(data.omega, band.rel_error, "C0-", lw=1.1, label=r"$|\Phi/G_N - 1|$")
        ax.set_xlabel(r"frequency $\omega$ (rad/s)")
        ax.set_ylabel("relative error")
        ax.grid(True, which="both", alpha=0.3)
    ax = fig.axes[0]
    e, s = band.rel_error, band.rel_error_std
    ax.fill_between(data.omega, e, e + z * s, color="C0", alpha=0.25, lw=0,
                    label=rf"$e + {z:.2f}\,\sigma(e)$ ({100 * level:g} % upper band, "
                          f"{unc.method})")
    ax.loglog(data.omega, z * band.rel_std, "C3--", lw=1.0,
              label=rf"model spread ${z:.2f}\,\sigma(\delta G_N/G_N)$")
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    if title is not None:
        ax.set_title(title)
    return fig


def _decimals(std):
    """Decimals that show two significant digits of ``std``."""
    return max(0, 1 - int(math.floor(math.log10(std)))) if std > 0 else 6


def _pm(value, std, digits=4):
    """``value ± std`` with the value rounded where the std's second digit is."""
    if not np.isfinite(value):
        return "–"
    if not np.isfinite(std):
        return f"{value:.{digits}g} (at bound)"
    d = _decimals(std)
    if abs(value) >= 1e-3 or value == 0:
        return f"{value:.{d}f} ± {std:.2g}"
    return f"{value:.{digits}g} ± {std:.2g}"


def _ci(value, std, z):
    if not np.isfinite(std):
        return "–"
    d = _decimals(z * std)
    lo, hi = value - z * std, value + z * std
    if abs(value) >= 1e-3:
        return f"[{lo:.{d}f}, {hi:.{d}f}]"
    return f"[{lo:.4g}, {hi:.4g}]"


def render_markdown(unc, *, level=0.95):
    """Markdown table of the modes, delay and gain with ± one standard deviation.

    Parameters
    ----------
    unc : ParameterUncertainty
    level : float
        Level of the confidence intervals in the last columns (normal quantile).

    Returns
    -------
    str
        One row per mode (natural frequency in Hz and rad/s, damping ratio, their
        intervals), then the delay (s) and the gain, and a line naming the noise source.
    """
    _check(unc, None)
    z = z_quantile(level)
    pct = f"{100 * level:g} %"
    lines = [f"| mode | f (Hz) | omega_n (rad/s) | zeta | omega_n {pct} CI | zeta {pct} CI |",
             "|---:|---:|---:|---:|---|---|"]
    for k, m in enumerate(unc.modes, start=1):
        lines.append(
            f"| {k} | {_pm(m.frequency_hz, m.frequency_hz_std)} | "
            f"{_pm(m.omega_n, m.omega_n_std)} | {_pm(m.zeta, m.zeta_std, 3)} | "
            f"{_ci(m.omega_n, m.omega_n_std, z)} | {_ci(m.zeta, m.zeta_std, z)} |")
    lines += ["", "| parameter | value ± std | " + pct + " CI |", "|---|---:|---|"]
    for name, value, std in (("delay (s)", unc.delay, unc.delay_std),
                             ("gain", unc.gain, unc.gain_std)):
        lines.append(f"| {name} | {_pm(value, std, 6)} | {_ci(value, std, z)} |")
    lines += ["", f"Standard deviations by the {unc.method} method; noise level from "
                  f"{unc.noise_source} (sigma^2 = {unc.sigma2:.3g} per real component of the "
                  f"weighted relative residual, {unc.dof} degrees of freedom)."]
    return "\n".join(lines) + "\n"

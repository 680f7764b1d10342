"""Figures of fits: Bode, relative error, pole-zero map, per-stage error, order sweep."""

import math

import numpy as np

from ..core.data import FrequencyData, dense_grid
from ..errors import OptionError
from ..core.metrics import relative_error as relative_error_of
from ..core.model import RationalDelayModel
from ._base import (_dense_grid, _is_result, _label_of, _labelled, _pyplot, finish_axes,
                    hz_axis, new_figure)

__all__ = ["bode", "relative_error", "pole_zero", "stage_errors", "sweep"]


def bode(result_or_data, models=None, *, labels=None, title=None, figsize=None,
         data_label=None, unit="rad/s"):
    """Bode plot of data (markers) and one or more models (lines), delay included.

    Parameters
    ----------
    result_or_data : FitResult or FrequencyData
        A fit result (its data and model are plotted) or the data alone.
    models : RationalDelayModel, FitResult, sequence or mapping of them, optional
        Further models to overlay; a mapping gives ``label -> model``. With a FitResult as
        first argument and no ``models``, its model is drawn.
    labels : sequence of str, optional
        Labels of the models (default: the result's method, or "model 1", ...).
    title : str, optional
        Figure title (default: the data name).
    figsize : (float, float), optional
        Inches (default (6.4, 5.6)).
    data_label : str, optional
        Legend label of the data (default "data" or the data name).
    unit : str
        Unit of the frequency axis, "rad/s" (default) or e.g. "rad/sample" for normalised
        frequency (labels only; the data are plotted as given).

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing the frequency axis: magnitude (dB) and unwrapped phase (degrees)
        against omega (rad/s, log scale), with the frequency in Hz on top.

    Notes
    -----
    Each model is evaluated on 2000 log-spaced points merged with the data frequencies, so
    the unwrapped phase follows the resonances. The data phase is drawn on the branch of
    the first model's phase point by point, ``arg G_N + angle(Phi/G_N)`` (the second term
    wrapped to (-180, 180] degrees, not unwrapped: noisy points at antiresonances cannot
    carry it away by multiples of 360 degrees); without a model it is drawn wrapped.
    """
    if _is_result(result_or_data):
        data = result_or_data.data
        base = [(_label_of(result_or_data, "model"), result_or_data.model)]
    elif isinstance(result_or_data, FrequencyData):
        data = result_or_data
        base = []
    else:
        raise OptionError("bode: the first argument must be a FitResult or a FrequencyData, "
                          f"got {type(result_or_data).__name__}")
    extra = []
    if models is not None:
        for lab, m in _labelled(models, None, "models"):
            if _is_result(m):
                extra.append((lab or _label_of(m, None), m.model))
            elif isinstance(m, RationalDelayModel):
                extra.append((lab, m))
            else:
                raise OptionError("bode: models must be RationalDelayModel or FitResult, got "
                                  f"{type(m).__name__}")
    pairs = base + extra
    if labels is not None:
        labels = list(labels)
        if len(labels) != len(pairs):
            raise OptionError(f"labels has {len(labels)} entries for {len(pairs)} models")
        pairs = [(lab, m) for lab, (_, m) in zip(labels, pairs)]
    pairs = [(lab or f"model {k + 1}", m) for k, (lab, m) in enumerate(pairs)]

    omega, phi = data.omega, data.response
    fig, (ax_mag, ax_ph) = new_figure(2, 1, figsize=figsize or (6.4, 5.6), sharex=True,
                                       height_ratios=(1, 1))
    grid = _dense_grid(omega)
    at_data = np.searchsorted(grid, omega)
    data_phase = None
    for k, (lab, model) in enumerate(pairs):
        g = model.frequency_response(grid)
        phase = np.unwrap(np.angle(g))
        color = f"C{k + 1}"
        ax_mag.semilogx(grid, 20 * np.log10(np.abs(g)), "-", color=color, lw=1.2, label=lab)
        ax_ph.semilogx(grid, np.rad2deg(phase), "-", color=color, lw=1.2, label=lab)
        if data_phase is None:
            # the data's branch follows the model point by point: model phase + the wrapped
            # phase of Phi/G_N (never accumulated, so noise at an antiresonance cannot carry
            # the data's phase off by multiples of 360 degrees)
            data_phase = phase[at_data] + np.angle(phi / g[at_data])
    if data_phase is None:
        data_phase = np.angle(phi)          # wrapped: unwrapping noisy data can run away
    dl = data_label or (f"data ({data.name})" if data.name else "data")
    mk = dict(marker="o", linestyle="none", markersize=2.5, markerfacecolor="none",
              markeredgewidth=0.6, color="C0", zorder=1)
    ax_mag.semilogx(omega, 20 * np.log10(np.abs(phi)), label=dl, **mk)
    ax_ph.semilogx(omega, np.rad2deg(data_phase), label=dl, **mk)

    ax_mag.set_ylabel("magnitude (dB)")
    ax_ph.set_ylabel("phase (degrees)")
    ax_ph.set_xlabel(rf"frequency $\omega$ ({unit})")
    ax_ph.set_xlim(omega[0], omega[-1])
    for ax in (ax_mag, ax_ph):
        finish_axes(ax)
    if unit == "rad/s":
        hz_axis(ax_mag)
    ax_mag.legend(loc="best", fontsize="small", framealpha=0.9)
    fig.suptitle(title if title is not None else (data.name or "Bode plot"))
    return fig


# ----------------------------------------------------------------------------- rel. error


def relative_error(results, *, labels=None, title=None, figsize=None, annotate_max=True,
                   reference=None, reference_label=None, truth=None, dense_factor=10,
                   unit="rad/s"):
    """Relative error ``|(G - G_N)/G_N|`` against frequency on log-log axes.

    Parameters
    ----------
    results : FitResult, sequence of FitResult or mapping label -> FitResult
        One curve per result (its ``rel_error`` at its data frequencies).
    labels : sequence of str, optional
        Curve labels (default: the mapping keys, else each result's method).
    title : str, optional
    figsize : (float, float), optional
    annotate_max : bool
        Draw each curve's maximum as a dashed horizontal line with its value.
    reference : float, optional
        A published maximum (e.g. the thesis's) drawn as a dotted black line.
    reference_label : str, optional
        Label of ``reference`` (default "reference").
    truth : callable, optional
        ``truth(omega) -> complex``, the true system: each curve also gets its error on a
        log grid ``dense_factor`` times denser than its data (thin line), the error
        between the samples.
    dense_factor : int
    unit : str
        Unit of the frequency axis, "rad/s" (default) or e.g. "rad/sample" (labels only).

    Returns
    -------
    matplotlib.figure.Figure
    """
    pairs = _labelled(results, labels, "results")
    fig, ax = new_figure(figsize=figsize)
    for k, (lab, res) in enumerate(pairs):
        if not _is_result(res):
            raise OptionError("relative_error: expected FitResult objects, got "
                              f"{type(res).__name__}")
        lab = lab or _label_of(res, f"model {k + 1}")
        rel = np.asarray(res.rel_error, float)
        omega = res.data.omega
        color = f"C{k}"
        if truth is not None:
            grid = dense_grid(omega, dense_factor)
            dense = relative_error_of(res.model, grid, np.asarray(truth(grid))).values
            ax.loglog(grid, dense, "-", color=color, lw=0.6, alpha=0.45,
                      label=f"{lab}, between the samples ({int(dense_factor)}x grid, max "
                            f"{np.max(dense):.3g})")
        ax.loglog(omega, rel, "-", color=color, lw=1.1, label=lab)
        if annotate_max and rel.size:
            i = int(np.argmax(rel))
            ax.axhline(rel[i], color=color, ls="--", lw=0.8, alpha=0.8)
            ax.plot(omega[i], rel[i], "o", color=color, ms=4)
            # keep the label inside the axes: left of the point when it is on the right
            span = math.log(omega[-1] / omega[0]) if omega[-1] > omega[0] else 1.0
            right = math.log(omega[i] / omega[0]) / span > 0.6
            hz = f" ({omega[i] / (2 * math.pi):.3g} Hz)" if unit == "rad/s" else ""
            ax.annotate(f"max {rel[i]:.3g} at {omega[i]:.3g} {unit}{hz}", (omega[i], rel[i]),
                        xytext=(-4 if right else 4, 4 + 11 * k), textcoords="offset points",
                        ha="right" if right else "left", va="bottom", fontsize="small",
                        color=color)
    if reference is not None:
        ax.axhline(float(reference), color="k", ls=":", lw=1.0,
                   label=f"{reference_label or 'reference'} ({float(reference):.4g})")
    ax.margins(x=0.02, y=0.12)           # head room for the max annotations
    ax.set_xlabel(rf"frequency $\omega$ ({unit})")
    ax.set_ylabel(r"relative error $|(G - G_N)/G_N|$")
    finish_axes(ax)
    if unit == "rad/s":
        hz_axis(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    if title is None:
        names = {getattr(r.data, "name", None) for _, r in pairs}
        title = ("relative error: " + names.pop()) if len(names) == 1 and None not in names \
            else "relative error"
    ax.set_title(title)
    return fig


# ----------------------------------------------------------------------------- poles/zeros


def pole_zero(model, *, zoom=None, title=None, figsize=None, unit="rad/s"):
    """Pole-zero map of the rational part of a model (the delay has neither).

    Parameters
    ----------
    model : RationalDelayModel or FitResult
    zoom : float or "auto", optional
        Add a second axes showing the poles and zeros with ``|s| <= zoom`` (rad/s), where
        low-frequency modes are otherwise hidden among the high-frequency ones.
        ``"auto"`` chooses a radius holding the lower half of the poles and zeros by
        magnitude.
    title : str, optional
    figsize : (float, float), optional
    unit : str
        Unit of the axes, "rad/s" (default) or e.g. "rad/sample" (labels only).

    Returns
    -------
    matplotlib.figure.Figure
        Poles as ``x``, zeros as ``o``, the integrator's pole at 0 as a filled square,
        the imaginary axis dashed. Axes in ``unit``.
    """
    if _is_result(model):
        model = model.model
    if not isinstance(model, RationalDelayModel):
        raise OptionError(f"pole_zero: expected a RationalDelayModel, got {type(model).__name__}")
    poles = model.poles()
    zeros = model.zeros()
    k = model.origin_order
    integ = poles[:max(k, 0)]
    poles = poles[max(k, 0):]
    origin_zeros = zeros[:max(-k, 0)]
    zeros = zeros[max(-k, 0):]
    if zoom == "auto":
        mags = np.sort(np.abs(np.concatenate([poles, zeros])))
        mags = mags[mags > 0]
        zoom = float(mags[(mags.size - 1) // 2]) * 1.2 if mags.size else None
    elif zoom is not None:
        try:
            zoom = float(zoom)
        except (TypeError, ValueError):
            raise OptionError(f"zoom must be a number > 0 (rad/s) or 'auto', got {zoom!r}") \
                from None
        if not (math.isfinite(zoom) and zoom > 0):
            raise OptionError(f"zoom must be a number > 0 (rad/s) or 'auto', got {zoom!r}")
    ncols = 1 if zoom is None else 2
    fig, axes = new_figure(1, ncols, figsize=figsize or ((6.4, 4.8) if ncols == 1
                                                          else (10.0, 4.6)))
    axes = [axes] if ncols == 1 else list(axes)
    for j, ax in enumerate(axes):
        ax.axvline(0, color="0.4", ls="--", lw=0.7, zorder=0)
        ax.axhline(0, color="0.7", lw=0.5, zorder=0)
        ax.plot(poles.real, poles.imag, "x", color="C3", ms=7, mew=1.3,
                label=f"poles ({poles.size})")
        ax.plot(zeros.real, zeros.imag, "o", color="C0", ms=7, mfc="none", mew=1.3,
                label=f"zeros ({zeros.size})")
        if integ.size:
            ax.plot([0.0], [0.0], "s", color="k", ms=5,
                    label="integrator pole" if integ.size == 1 else
                    f"{integ.size} poles at the origin")
        if origin_zeros.size:
            ax.plot([0.0], [0.0], "D", color="k", mfc="none", ms=6,
                    label=f"{origin_zeros.size} zero{'s' if origin_zeros.size > 1 else ''} "
                          "at the origin")
        ax.set_xlabel(f"real part ({unit})")
        ax.set_ylabel(f"imaginary part ({unit})")
        finish_axes(ax)
        # wide ranges (a zero far above the band) and tiny real parts: few, short labels
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(5))
        ax.ticklabel_format(axis="both", style="sci", scilimits=(-2, 4), useMathText=True)
        if j == 1:
            near = np.concatenate([poles, zeros, integ])
            _pz_limits(ax, near[np.abs(near) <= zoom], zoom)
            ax.set_title(f"near the origin: |s| ≤ {zoom:.3g} {unit}", fontsize="medium")
        else:
            allp = np.concatenate([poles, zeros, integ])
            _pz_limits(ax, allp, float(np.max(np.abs(allp.imag))) if allp.size else 1.0)
            if ncols == 2:
                ax.set_title("all", fontsize="medium")
    axes[0].legend(loc="best", fontsize="small", framealpha=0.9)
    stab = ("NOT stable" if not model.is_stable() else "stable" if
            model.is_stable(strict=True) else "marginally stable: poles on the axis")
    mph = ("NOT minimum phase" if not model.is_minimum_phase() else "minimum phase" if
           model.is_minimum_phase(strict=True) else "zeros on the axis")
    fig.suptitle(title if title is not None else f"poles and zeros of $P_N$ ({stab}, {mph})")
    return fig


def _pz_limits(ax, points, im_max):
    """Imaginary axis +-im_max; real axis from the leftmost point to a little right of 0
    (the real parts of lightly damped modes are much smaller than their imaginary parts,
    so the axes are not scaled equally)."""
    re_min = float(np.min(points.real)) if points.size else 0.0
    # real roots only (first-order basis): a vertical extent like the horizontal one
    im_max = max(float(im_max), 0.25 * abs(re_min), 1e-12)
    width = -re_min if re_min < 0 else 0.1 * im_max
    ax.set_xlim(re_min - 0.08 * width, 0.08 * width)
    ax.set_ylim(-1.06 * im_max, 1.06 * im_max)


# ----------------------------------------------------------------------------- stages


def stage_errors(results_by_label, *, title=None, figsize=None, window=False):
    """Maximum relative error over all data after each stage, one line per variant.

    Parameters
    ----------
    results_by_label : mapping label -> FitResult, or FitResult, or sequence of FitResult
        Variants to compare (e.g. methods or ablation settings).
    title : str, optional
    figsize : (float, float), optional
    window : bool
        Also draw the maximum over the stage's window (dotted).

    Returns
    -------
    matplotlib.figure.Figure
        Stage number on x (0: gain/delay; N: after adding section N; the final all-data
        stage is drawn with a filled marker), max relative error on a log y axis.
    """
    pairs = _labelled(results_by_label, None, "results")
    fig, ax = new_figure(figsize=figsize)
    for k, (lab, res) in enumerate(pairs):
        stages = getattr(res, "stages", None)
        if stages is None:
            raise OptionError("stage_errors: expected FitResult objects (with .stages), got "
                              f"{type(res).__name__}")
        lab = lab or _label_of(res, f"variant {k + 1}")
        x = np.array([s.stage for s in stages], float)
        y = np.array([s.max_rel_error for s in stages], float)
        color = f"C{k}"
        ax.semilogy(x, y, "-o", color=color, ms=3.5, lw=1.1, label=lab)
        final = [i for i, s in enumerate(stages)
                 if s.stage > s.n_sections or getattr(s.kind, "value", s.kind) == "final"]
        n_points = getattr(getattr(res, "data", None), "n_points", None)
        if not final and stages and n_points and stages[-1].window >= n_points:
            final = [len(stages) - 1]    # the last section's window was all the data
        if final:
            ax.semilogy(x[final], y[final], "D", color=color, ms=6)
            ax.annotate("final", (x[final[-1]], y[final[-1]]), xytext=(-4, 6), ha="right",
                        textcoords="offset points", fontsize="small", color=color)
        if window:
            yw = np.array([s.max_rel_error_window for s in stages], float)
            ax.semilogy(x, yw, ":", color=color, lw=1.0, label=f"{lab} (window)")
    ax.set_xlabel("stage (0: gain and delay; N: section N added; ◆: final, all data)")
    ax.set_ylabel("max relative error over all data")
    ax.xaxis.get_major_locator().set_params(integer=True)
    finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    ax.set_title(title if title is not None else "error after each stage")
    return fig


def sweep(result):
    """Figure of an order sweep: max (and dense-grid) relative error, delay and time
    against the order of P_N.

    Parameters
    ----------
    result : freqid_casadi.fitting.sweep.SweepResult

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _pyplot()
    orders = [r.order for r in result.rows]
    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
    ax = axes[0]
    ax.semilogy(orders, [r.max_rel_error for r in result.rows], "o-", label="max, data points")
    dense = [r.max_rel_error_dense for r in result.rows]
    if any(np.isfinite(dense)):
        ax.semilogy(orders, dense, "s--", label="max, 10x denser grid")
    ax.semilogy(orders, [r.rms_rel_error for r in result.rows], "^:", label="RMS")
    if result.target is not None:
        ax.axhline(result.target, color="k", ls=":", label=f"target {result.target:g}")
    ax.set_ylabel("relative error")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    axes[1].plot(orders, [r.delay for r in result.rows], "o-")
    axes[1].set_ylabel("delay h (s)")
    axes[1].grid(True, alpha=0.3)
    axes[2].plot(orders, [r.wall_time for r in result.rows], "o-")
    axes[2].set_ylabel("time (s)")
    axes[2].set_xlabel("order of $P_N$")
    axes[2].grid(True, alpha=0.3)
    if len(orders) <= 12:                          # the orders fitted, no fractions
        axes[2].set_xticks(orders)
    else:
        from matplotlib.ticker import MaxNLocator

        axes[2].xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(f"order sweep: {result.data_name or 'data'}")
    fig.tight_layout()
    return fig

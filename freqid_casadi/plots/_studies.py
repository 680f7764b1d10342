"""Figures of computed curves, for the studies: lines, Bode of several responses, a
symmetric-log pole-zero map, per-variant bars and a message panel."""

import math

import numpy as np

from ..errors import OptionError
from ._base import finish_axes, new_figure

__all__ = ["line_plot", "bode_curves", "pole_zero_symlog", "variant_bars", "message_figure",
           "line_style"]

_LINESTYLES = ("-", "--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1)))


def line_style(k):
    """The k-th style of a set of curves on one axes (colour ``C<k>``, the first line
    thicker, six dash patterns in turn): a dict of ``Axes.plot`` keywords."""
    return dict(color=f"C{k}", lw=1.6 if k == 0 else 1.0, ls=_LINESTYLES[k % 6])


def line_plot(lines, *, xlabel, ylabel, title, xscale="log", yscale="log", hlines=(),
              vlines=(), legend_fontsize="small", figsize=None, ylim=None):
    """Lines on one axes (log-log by default), with horizontal and vertical markers.

    Parameters
    ----------
    lines : sequence of dict
        One dict per line: ``x`` and ``y`` (array_like, same length), optional ``label``
        and any ``Axes.plot`` keyword (``color``, ``lw``, ``ls``, ``marker``, ``ms``, ...).
    xlabel, ylabel, title : str
        Axis labels (with units) and the axes title.
    xscale, yscale : str
        ``"log"`` (default) or ``"linear"``.
    hlines, vlines : sequence of dict
        Reference lines: ``y`` (or ``x``), optional ``label`` and ``Axes.axhline`` /
        ``axvline`` keywords.
    legend_fontsize : str
        Font size of the legend (no legend when no item has a label).
    figsize : (float, float), optional
        Inches (default (6.4, 4.8)).
    ylim : (float or None, float or None), optional
        Limits of the y axis (None: automatic at that end).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    OptionError
        If a line lacks ``x`` or ``y`` or they differ in length.
    """
    fig, ax = new_figure(figsize=figsize)
    labelled = False
    for k, line in enumerate(lines):
        kw = dict(line)
        try:
            x, y = np.asarray(kw.pop("x"), float), np.asarray(kw.pop("y"), float)
        except KeyError:
            raise OptionError(f"lines[{k}] needs 'x' and 'y'") from None
        if x.shape != y.shape:
            raise OptionError(f"lines[{k}]: x has shape {x.shape}, y {y.shape}; give one y "
                              "per x")
        labelled |= kw.get("label") is not None
        ax.plot(x, y, **kw)
    for kw in hlines:
        kw = dict(kw)
        labelled |= kw.get("label") is not None
        ax.axhline(kw.pop("y"), **kw)
    for kw in vlines:
        kw = dict(kw)
        labelled |= kw.get("label") is not None
        ax.axvline(kw.pop("x"), **kw)
    ax.set_xscale(xscale)
    ax.set_yscale(yscale)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if ylim is not None:
        ax.set_ylim(*ylim)
    finish_axes(ax)
    if labelled:
        ax.legend(loc="best", fontsize=legend_fontsize, framealpha=0.9)
    return fig


def bode_curves(omega, responses, *, reference=None, title=None, phase_limits=None,
                xlabel=None):
    """Magnitude (dB) and phase (degrees) of several complex responses on one grid.

    Parameters
    ----------
    omega : array_like of float, shape (M,)
        Frequencies in rad/s (log axis).
    responses : mapping label -> complex array_like, shape (M,)
        The curves, drawn with :func:`line_style` in order; phases unwrapped.
    reference : (str, complex array_like of shape (M,)), optional
        A curve drawn thick and grey behind the others (e.g. the true system or the
        data), phase unwrapped; every other curve's unwrapped phase is shifted by the
        multiple of 360 degrees that puts it nearest the reference's at the lowest
        frequency, so all curves share one branch.
    title : str, optional
    phase_limits : (float, float), optional
        Limits of the phase axis in degrees.
    xlabel : str, optional
        Label of the frequency axis; default "frequency omega (rad/s)" (pass e.g.
        "(rad/sample)" for normalised frequency).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, (ax_m, ax_p) = new_figure(2, 1, figsize=(6.4, 5.6), sharex=True)
    omega = np.asarray(omega, float)
    ref_phase0 = None
    if reference is not None:
        label, g = reference[0], np.asarray(reference[1])
        phase = np.unwrap(np.angle(g))
        ref_phase0 = phase[0]
        ax_m.semilogx(omega, 20 * np.log10(np.abs(g)), "k-", lw=2.4, alpha=0.35, label=label)
        ax_p.semilogx(omega, np.rad2deg(phase), "k-", lw=2.4, alpha=0.35)
    for k, (label, g) in enumerate(responses.items()):
        g = np.asarray(g)
        st = line_style(k)
        phase = np.unwrap(np.angle(g))
        if ref_phase0 is not None:
            phase = phase + 2 * np.pi * np.round((ref_phase0 - phase[0]) / (2 * np.pi))
        ax_m.semilogx(omega, 20 * np.log10(np.abs(g)), label=label, **st)
        ax_p.semilogx(omega, np.rad2deg(phase), **st)
    ax_m.set_ylabel("magnitude (dB)")
    ax_p.set_ylabel("phase (degrees)")
    ax_p.set_xlabel(xlabel or r"frequency $\omega$ (rad/s)")
    if phase_limits is not None:
        ax_p.set_ylim(*phase_limits)
    for ax in (ax_m, ax_p):
        finish_axes(ax)
    ax_m.legend(loc="best", fontsize="small", framealpha=0.9)
    if title is not None:
        fig.suptitle(title)
    return fig


def pole_zero_symlog(model, *, title):
    """Pole-zero map on symmetric-log axes, for models whose roots span many decades and
    may lie in the right half plane (e.g. the unconstrained baselines).

    Parameters
    ----------
    model : object with ``poles()`` and ``zeros()``
        Returning complex arrays (rad/s).
    title : str

    Returns
    -------
    matplotlib.figure.Figure
        Poles ``x``, zeros ``o`` (the legend counts those in the RHP), imaginary axis dashed.
    """
    fig, ax = new_figure()
    p, z = np.asarray(model.poles()), np.asarray(model.zeros())
    ax.axvline(0, color="0.4", ls="--", lw=0.7, zorder=0)
    ax.plot(p.real, p.imag, "x", color="C3", ms=7, mew=1.3, label=f"poles ({p.size})")
    ax.plot(z.real, z.imag, "o", color="C0", ms=7, mfc="none", mew=1.3,
            label=f"zeros ({z.size}, {int(np.count_nonzero(z.real > 0))} in the RHP)")
    pts = np.concatenate([p, z])
    lim = float(np.max(np.abs(pts))) * 1.05 if pts.size else 1.0
    # symmetric log axes: the roots span several decades; a wide linear region around 0
    # keeps the tick labels -thresh, 0, +thresh apart
    thresh = 10.0 ** math.floor(math.log10(max(lim * 1e-4, 1e-6)))
    ax.set_xscale("symlog", linthresh=thresh, linscale=2.0)
    ax.set_yscale("symlog", linthresh=thresh, linscale=2.0)
    ax.set_xlabel("real part (rad/s, symmetric log scale)")
    ax.set_ylabel("imaginary part (rad/s, symmetric log scale)")
    ax.set_title(title)
    finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    return fig


def variant_bars(rows, *, title, baseline=None):
    """Final max error and wall time of variants as horizontal bars on log scales.

    Parameters
    ----------
    rows : sequence of dict
        One per variant, top to bottom: ``label`` (str), ``group`` (str; one colour per
        group), ``max_rel_error`` and ``wall_time`` (s) (floats, or None for a failed
        variant, drawn as "FAILED").
    title : str
    baseline : dict, optional
        A row whose error and time are drawn as dashed vertical lines.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib import ticker

    n = len(rows)
    fig, (ax_e, ax_t) = new_figure(1, 2, figsize=(10.0, 0.35 * n + 1.8), sharey=True)
    y = np.arange(n)[::-1]
    groups = list(dict.fromkeys(r["group"] for r in rows))
    for yi, r in zip(y, rows):
        color = f"C{groups.index(r['group'])}"
        if r["max_rel_error"] is None:
            ax_e.annotate("FAILED", (0.02, yi), xycoords=("axes fraction", "data"),
                          va="center", color="C3", fontsize="small")
            continue
        for ax, value, text in ((ax_e, r["max_rel_error"], f"{r['max_rel_error']:.3g}"),
                                (ax_t, r["wall_time"], f"{r['wall_time']:.3g} s")):
            ax.barh(yi, value, color=color, alpha=0.85)
            ax.annotate(text, (value, yi), xytext=(3, 0), textcoords="offset points",
                        va="center", fontsize="x-small")
    if baseline is not None:
        ax_e.axvline(baseline["max_rel_error"], color="k", ls="--", lw=0.8)
        ax_t.axvline(baseline["wall_time"], color="k", ls="--", lw=0.8)
    for ax in (ax_e, ax_t):
        ax.set_xscale("log")
    ax_t.xaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    ax_t.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
    ax_t.xaxis.set_minor_formatter(ticker.NullFormatter())
    ax_e.set_yticks(y, [r["label"] for r in rows], fontsize="small")
    ax_e.set_xlabel("final max relative error (dashed: IPOPT default)")
    ax_t.set_xlabel("wall time (s)")
    for ax in (ax_e, ax_t):
        finish_axes(ax)
        ax.margins(x=0.25)
    fig.suptitle(title)
    return fig


def message_figure(text):
    """A figure holding only ``text`` (str), centred: the place of a figure that has no data."""
    fig, ax = new_figure()
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes)
    ax.set_axis_off()
    return fig

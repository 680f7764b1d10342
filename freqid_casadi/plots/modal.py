"""Stabilization diagram (layer L5). matplotlib is imported inside the functions only."""

import numpy as np

from ..errors import OptionError

__all__ = ["stabilization_diagram", "mode_shape_figure", "MARKERS"]

#: marker, colour and legend label of each pole status
MARKERS = {
    "new": ("o", "0.6", "new"),
    "stable-frequency": ("x", "tab:blue", "stable in frequency"),
    "stable-frequency-damping": ("*", "tab:red", "stable in frequency and damping"),
}


def stabilization_diagram(result, *, title=None, figsize=(8.0, 5.0), log_frequency=None):
    """Poles of every order over the summed FRF magnitude.

    Parameters
    ----------
    result : freqid_casadi.modal.survey.StabilizationResult
    title : str, optional
    figsize : (float, float)
        Inches.
    log_frequency : bool, optional
        Logarithmic frequency axis; default when the data span more than two decades.

    Returns
    -------
    matplotlib.figure.Figure
        x: frequency (Hz); left axis: model order (number of shared poles), one marker per
        pole by status (:data:`MARKERS`); right axis: ``sum_c |Phi_c|`` (log scale);
        dashed vertical lines: the automatically selected modes.
    """
    if not hasattr(result, "orders") or not hasattr(result, "poles"):
        raise OptionError(f"stabilization_diagram needs a StabilizationResult, got "
                          f"{type(result).__name__}")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    f_hz = result.omega / (2 * np.pi)
    if log_frequency is None:
        log_frequency = f_hz[-1] / f_hz[0] > 100
    ax2 = ax.twinx()
    ax2.plot(f_hz, result.summed_magnitude, color="0.3", linewidth=0.8,
             label="sum of |FRF|")
    ax2.set_yscale("log")
    ax2.set_ylabel("sum over channels of |FRF|")
    for status, (marker, colour, label) in MARKERS.items():
        pts = [(p.frequency_hz, p.order) for p in result.poles if p.status == status]
        if pts:
            x, y = np.array(pts).T
            ax.scatter(x, y, marker=marker, color=colour, s=28 if marker == "*" else 18,
                       label=label, zorder=3, linewidths=1.0)
    for k, m in enumerate(result.modes):
        ax.axvline(m.frequency_hz, color="tab:green", linestyle="--", linewidth=0.8,
                   label="selected mode" if k == 0 else None, zorder=1)
    ax.set_xlim(f_hz[0], f_hz[-1])
    if log_frequency:
        ax.set_xscale("log")
    ax.set_ylim(0, result.orders[-1] + 3)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("model order (number of shared poles)")
    ax.set_zorder(ax2.get_zorder() + 1)
    ax.patch.set_visible(False)
    if ax.get_legend_handles_labels()[0]:      # no poles in the band: no empty legend
        ax.legend(loc="lower left", fontsize=8, framealpha=0.9)
    ax.set_title(title or f"Stabilization diagram ({len(result.modes)} modes selected; "
                 f"tolerances {100 * result.freq_tol:g} % frequency, "
                 f"{100 * result.damping_tol:g} % damping)", fontsize=10)
    ax.grid(True, alpha=0.3)
    return fig


def mode_shape_figure(shapes, k, *, figsize=(6.4, 3.2)):
    """One mode's shape against the channels' coordinates (or channel numbers).

    Parameters
    ----------
    shapes : freqid_casadi.core.modes.ModeShapes
    k : int
        Mode index (0-based).
    figsize : (float, float)
        Inches.

    Returns
    -------
    matplotlib.figure.Figure
        The aligned shape's real part (solid, markers) and imaginary part (dashed; near 0
        for a real mode) against the first coordinate (sorted) or the channel number; the
        title gives the frequency, damping, MPC and MPD.
    """
    if not hasattr(shapes, "aligned") or not 0 <= int(k) < len(shapes):
        raise OptionError(f"mode_shape_figure needs ModeShapes and a mode index in "
                          f"[0, {len(getattr(shapes, 'aligned', ()))}), got {k!r}")
    import matplotlib.pyplot as plt

    k = int(k)
    fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    n = shapes.aligned.shape[1]
    if shapes.coordinates is not None:
        x, xlabel = shapes.coordinates[:, 0], "channel coordinate"
    else:
        x, xlabel = np.arange(1, n + 1, dtype=float), "channel"
    order = np.argsort(x, kind="stable")
    a = shapes.aligned[k]
    ax.axhline(0.0, color="0.6", linewidth=0.8)
    ax.plot(x[order], a.real[order], "o-", color="tab:blue", label="real part")
    ax.plot(x[order], a.imag[order], "x--", color="tab:orange", label="imaginary part")
    if shapes.coordinates is None:
        ax.set_xticks(x, list(shapes.names), rotation=45, fontsize=7)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("shape (largest component +1)")
    ax.set_ylim(-1.15, 1.15)
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"mode {k + 1}: {shapes.frequency_hz[k]:.6g} Hz, zeta "
                 f"{100 * shapes.zeta[k]:.3g} %, MPC {shapes.mpc[k]:.3f}, MPD "
                 f"{shapes.mpd_deg[k]:.1f} deg", fontsize=10)
    return fig

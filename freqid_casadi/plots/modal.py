"""Stabilization diagram (layer L5). matplotlib is imported inside the functions only."""

import numpy as np

from ..errors import OptionError

__all__ = ["stabilization_diagram", "MARKERS"]

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

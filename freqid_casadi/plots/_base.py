"""Shared pieces of the figures: lazy matplotlib, new axes, axis finish, atomic PNG files."""

import io
import math
import os
from collections.abc import Mapping

import numpy as np

from .._textio import atomic_write_bytes
from ..errors import FreqidError, OptionError
from ..core.model import RationalDelayModel

__all__ = ["new_figure", "finish_axes", "save_figure", "MatplotlibMissingError", "DPI"]

#: Resolution (dots per inch) of the PNG files written by :func:`save_figure`.
DPI = 150

_FIGSIZE = (6.4, 4.8)
_DENSE_POINTS = 2000


class MatplotlibMissingError(FreqidError, ImportError):
    """matplotlib is needed for plotting but is not installed."""


def _pyplot():
    """Import and return ``matplotlib.pyplot`` or raise :class:`MatplotlibMissingError`."""
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise MatplotlibMissingError(
            f"plotting needs matplotlib, which could not be imported ({exc}); "
            "install it with: pip install matplotlib") from exc
    return plt


def new_figure(nrows=1, ncols=1, figsize=None, **kw):
    """A new figure with constrained layout: ``(fig, axes)`` as ``plt.subplots`` returns.

    Parameters
    ----------
    nrows, ncols : int
        Grid of axes.
    figsize : (float, float), optional
        Inches (default (6.4, 4.8)).
    **kw
        Further keywords of ``matplotlib.pyplot.subplots`` (``sharex``, ...).

    Returns
    -------
    (matplotlib.figure.Figure, Axes or ndarray of Axes)
    """
    plt = _pyplot()
    fig, axes = plt.subplots(nrows, ncols, figsize=figsize or _FIGSIZE, layout="constrained",
                             **kw)
    return fig, axes


def finish_axes(ax):
    """The package's axis style: major and minor grid, inward ticks on all four sides."""
    ax.grid(True, which="major", alpha=0.5, linewidth=0.6)
    ax.grid(True, which="minor", alpha=0.2, linewidth=0.4)
    ax.tick_params(which="both", direction="in", top=True, right=True)


def hz_axis(ax):
    """A top axis in Hz over ``ax``, whose x axis is in rad/s (measurements are in Hz).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Its top ticks are replaced by the Hz axis's.

    Returns
    -------
    matplotlib.axes.Axes
        The secondary axis.
    """
    two_pi = 2 * math.pi
    sec = ax.secondary_xaxis("top", functions=(lambda w: w / two_pi, lambda f: f * two_pi))
    sec.set_xlabel("frequency f (Hz)")
    sec.tick_params(which="both", direction="in")
    ax.tick_params(which="both", top=False)
    return sec


# ----------------------------------------------------------------------------- inputs


def _is_result(obj):
    """Duck-typed FitResult: has a model and data."""
    return (hasattr(obj, "model") and hasattr(obj, "data")
            and isinstance(getattr(obj, "model"), RationalDelayModel))


def _label_of(result, default):
    method = getattr(result, "method", None)
    return str(method) if method else default


def _labelled(items, labels, what):
    """Normalise ``items`` (one object, a sequence or a mapping label -> object) to a list
    of (label, object); ``labels`` overrides the labels."""
    if isinstance(items, Mapping):
        pairs = [(str(k), v) for k, v in items.items()]
    elif isinstance(items, (list, tuple)):
        pairs = [(None, v) for v in items]
    else:
        pairs = [(None, items)]
    if not pairs:
        raise OptionError(f"{what}: nothing to plot (got an empty collection)")
    if labels is not None:
        labels = list(labels)
        if len(labels) != len(pairs):
            raise OptionError(f"labels has {len(labels)} entries for {len(pairs)} {what}; "
                              "give one label per item")
        pairs = [(str(lab), v) for lab, (_, v) in zip(labels, pairs)]
    return pairs


def _dense_grid(omega, n=_DENSE_POINTS):
    """Log-spaced grid over the data range, merged with the data frequencies."""
    lo, hi = float(omega[0]), float(omega[-1])
    if hi > lo:
        grid = np.logspace(math.log10(lo), math.log10(hi), n)
    else:
        grid = np.array([lo])
    return np.union1d(grid, omega)


def save_figure(fig, path, *, dpi=DPI):
    """Write ``fig`` to ``path`` atomically and close it.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or os.PathLike
        Target file; the format follows the extension (``.png`` if there is none).
    dpi : float
        Resolution (default :data:`DPI`, 150).

    Returns
    -------
    str
        The path written.

    Notes
    -----
    The image is rendered to memory, written to a temporary file in the target's folder and
    moved over the target with ``os.replace``: an interrupted run leaves no partial file.
    The figure is closed even if writing fails.
    """
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lstrip(".").lower() or "png"
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format=ext, dpi=dpi)
        atomic_write_bytes(path, buf.getvalue())
        os.chmod(path, _file_mode())
    finally:
        _pyplot().close(fig)
    return path


def _file_mode(directory=False):
    """Permissions of a new file (or folder) under the current umask; temporary files are
    created 0600/0700, and a finished report should not keep that."""
    mask = os.umask(0o022)
    os.umask(mask)
    return (0o777 if directory else 0o666) & ~mask

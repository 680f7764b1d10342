"""Figures of fits and of the studies' curves (layer L5).

matplotlib is imported inside the functions, never at module import, so ``import
freqid_casadi`` (and ``import freqid_casadi.plots``) stays free of it (docs/style.md §3). Without
matplotlib every function raises :class:`MatplotlibMissingError`, an ``ImportError`` that
says how to install it.

Every function takes results (or data and models) and returns a
``matplotlib.figure.Figure``; none calls ``show()``. Write a figure with
:func:`save_figure`, which writes the PNG atomically and closes the figure.

Conventions: frequencies in rad/s on a log axis, magnitudes in dB, phases in degrees
(unwrapped), relative errors ``|(G - G_N)/G_N|`` on log-log axes (SPEC §1).

Modules: ``_base`` (lazy matplotlib, :func:`new_figure`, :func:`finish_axes`,
:func:`save_figure`), ``_fits`` (figures of FitResults: :func:`bode`,
:func:`relative_error`, :func:`pole_zero`, :func:`stage_errors`, :func:`sweep`) and
``_studies`` (figures of computed curves: :func:`line_plot`, :func:`bode_curves`,
:func:`pole_zero_symlog`, :func:`variant_bars`, :func:`message_figure`); every name is
re-exported here.
"""

from ._base import DPI, MatplotlibMissingError, finish_axes, new_figure, save_figure
from ._base import _file_mode, _pyplot  # noqa: F401 (report._set_modes uses _file_mode)
from ._fits import bode, pole_zero, relative_error, stage_errors, sweep
from ._studies import (bode_curves, line_plot, line_style, message_figure,
                       pole_zero_symlog, variant_bars)

__all__ = ["bode", "relative_error", "pole_zero", "stage_errors", "sweep", "save_figure",
           "line_plot", "line_style", "bode_curves", "pole_zero_symlog", "variant_bars",
           "message_figure", "new_figure", "finish_axes", "MatplotlibMissingError", "DPI"]

# the names of the single-file plots.py, for modules written against it
_new_figure, _finish_axes = new_figure, finish_axes

"""Options shared by every command that reads a data file (layer L6).

:func:`add_data_options` adds ``--freq-unit hz|rad/s`` and ``--columns LIST`` to a parser;
:func:`load_data` loads a file with them (:func:`freqid_casadi.loaders.load`) and prints the
reader's notes (e.g. rows dropped at zero frequency) as ``note: ...`` lines on stderr
instead of Python warning text.
"""

import argparse
import contextlib
import sys
import warnings

from .loaders import DataWarning, load
from .errors import OptionError
from ._table import parse_columns

__all__ = ["add_data_options", "load_data", "load_options", "notes_to_stderr"]


def _columns(text):
    try:
        parse_columns(text)
    except OptionError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace("columns", "", 1).lstrip(": "))
    return text


def add_data_options(parser):
    """Add ``--freq-unit`` and ``--columns`` to ``parser``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The sub-command's parser; returned for chaining.
    """
    parser.add_argument(
        "--freq-unit", choices=("hz", "rad/s"), type=str.lower, metavar="hz|rad/s",
        help="unit of the frequency column when the file does not say it (a headerless "
             "file, a header 'f' or 'freq')")
    parser.add_argument(
        "--columns", type=_columns, metavar="LIST",
        help="names of the file's columns, e.g. 'f,re,im' or 'freq_hz,mag_db,phase_deg' "
             "(omega/w rad/s, freq_hz Hz, f with --freq-unit; re,im; mag or mag_db with "
             "phase_deg or phase_rad; complex; skip)")
    return parser


def load_options(args):
    """The ``freq_unit`` and ``columns`` keywords of :func:`~freqid_casadi.loaders.load`.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments (absent options count as not given).
    """
    return dict(freq_unit=getattr(args, "freq_unit", None),
                columns=getattr(args, "columns", None))


@contextlib.contextmanager
def notes_to_stderr():
    """Within the block, :class:`~freqid_casadi.loaders.DataWarning` s are printed as
    ``note: ...`` lines on stderr after the block succeeds (none if it raises); other
    warnings are passed on unchanged."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DataWarning)
        yield
    for w in caught:
        if issubclass(w.category, DataWarning):
            sys.stderr.write(f"note: {' '.join(str(w.message).split())}\n")
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def load_data(args, path):
    """Load ``path`` with the options in ``args``; reader notes go to stderr as ``note:``.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments with ``freq_unit`` and ``columns`` (see :func:`load_options`).
    path : str
        The data file.

    Returns
    -------
    FrequencyData

    Raises
    ------
    DataError, OptionError
        As :func:`freqid_casadi.loaders.load`; no note is printed before an error.
    """
    with notes_to_stderr():
        data = load(path, **load_options(args))
    return data

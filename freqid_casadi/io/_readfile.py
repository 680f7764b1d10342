"""Reading one regular file safely, and turning columns into FrequencyData (layer L1).

Shared by every reader (:mod:`freqid_casadi.io.loaders`, the UFF and Touchstone readers): a
path is opened only if it is a regular file within the size limit (a FIFO, a device or a
folder is refused before any read, so nothing hangs), and rows at zero frequency are
dropped with a stated :class:`DataWarning`.
"""

import math
import numbers
import os
import stat
import warnings

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, DataWarning, OptionError

__all__ = ["DataWarning", "read_regular_file", "parse_band", "MAX_FILE_BYTES", "MAX_ROWS",
           "MAX_ELEMENTS"]

#: Largest file any reader accepts, in bytes.
MAX_FILE_BYTES = 256 * 2 ** 20
#: Most data rows a text reader accepts.
MAX_ROWS = 5_000_000
#: Most elements of one array in an ``.npz`` or ``.mat`` file.
MAX_ELEMENTS = 50_000_000




# --------------------------------------------------------------------------- files

def _check_file(path):
    """The path as str, after the checks that need no read (exists, not a folder, readable)."""
    try:
        path = os.fspath(path)
    except TypeError:
        raise DataError(f"path must be a file name, got {type(path).__name__}") from None
    if not isinstance(path, str):
        path = os.fsdecode(path)
    if not path.strip():
        raise DataError(f"data file name is empty ({path!r}); give the path of the file")
    if not os.path.exists(path):
        raise DataError(f"data file not found: {path!r}; check the path")
    if os.path.isdir(path):
        raise DataError(f"{path!r} is a directory, not a data file; name the file inside it")
    if not os.access(path, os.R_OK):
        raise DataError(f"data file {path!r} is not readable; check its permissions")
    return path


def _kind_of(mode):
    kinds = {stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFCHR: "a character device",
             stat.S_IFBLK: "a block device", stat.S_IFSOCK: "a socket",
             stat.S_IFDIR: "a directory"}
    return kinds.get(stat.S_IFMT(mode), "not a regular file")


def read_regular_file(path, what="data file"):
    """Read a whole regular file, bounded by :data:`MAX_FILE_BYTES`.

    Parameters
    ----------
    path : str or path-like
    what : str
        How the file is called in messages.

    Returns
    -------
    path : str
    payload : bytes

    Raises
    ------
    DataError
        Missing or unreadable file; a folder, FIFO, device or socket (refused before any
        read: opened non-blocking and checked with ``fstat``); a file above the size limit.
    """
    path = _check_file(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise DataError(f"cannot open {what} {path!r}: {exc.strerror}; check the path") \
            from None
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fh.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise DataError(f"{what} {path!r} is {_kind_of(info.st_mode)}, not a regular "
                            "file; save the data to a file and give its path")
        if info.st_size > MAX_FILE_BYTES:
            raise DataError(_too_big(path, what, info.st_size))
        try:
            payload = fh.read(MAX_FILE_BYTES + 1)
        except OSError as exc:
            raise DataError(f"cannot read {what} {path!r}: {exc.strerror}") from None
    if len(payload) > MAX_FILE_BYTES:
        raise DataError(_too_big(path, what, len(payload)))
    return path, payload


def _too_big(path, what, size):
    return (f"{what} {path!r} holds {size} bytes, above the limit of {MAX_FILE_BYTES} bytes "
            "(freqid_casadi.io.loaders.MAX_FILE_BYTES); thin the data or raise that limit")


def _stem(path):
    """The file's name without folder and extension, the data's default name; bytes that
    are not UTF-8 (surrogates from os.fsdecode) are written as ``\\udcff`` escapes, so the
    name can be printed, drawn and written into reports."""
    stem = os.path.splitext(os.path.basename(path))[0]
    return stem.encode("utf-8", "backslashreplace").decode("utf-8")


def parse_band(band):
    """``(lo, hi)`` as floats from a user's ``band=``, or None.

    Parameters
    ----------
    band : (float, float) or None
        Lowest and highest frequency kept, ``0 <= lo < hi``, in the file's frequency unit.

    Raises
    ------
    OptionError
        Not two finite numbers with ``0 <= lo < hi``.
    """
    if band is None:
        return None
    try:
        lo, hi = band
    except (TypeError, ValueError):
        raise OptionError(f"band must be a pair (lo, hi) of frequencies in the file's unit, "
                          f"got {band!r:.60}; e.g. band=(65, 1000)") from None
    if not all(isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
               for v in (lo, hi)) or not 0 <= lo < hi:
        raise OptionError(f"band=({lo!r:.20}, {hi!r:.20}) must be two finite numbers with "
                          "0 <= lo < hi (in the file's frequency unit); e.g. band=(65, 1000)")
    return float(lo), float(hi)


#: Relative slack of a band's edges (:func:`_in_band`): 8 units of rounding.
_EDGE = 8 * np.finfo(float).eps


def _in_band(path, omega, band, scale, unit):
    """Mask of the points of ``omega`` (rad/s) inside ``band`` (file unit, ``omega = scale
    * f``), with a DataWarning saying how many were dropped; DataError when none is left."""
    lo, hi = band
    f = omega / scale
    # the file's frequency went to rad/s and back: a point on an edge (1000 Hz read as
    # 999.9999999999999) is inside the band, within a few units of rounding
    lo, hi = lo * (1 - _EDGE), hi * (1 + _EDGE)
    below, above = int(np.sum(f < lo)), int(np.sum(f > hi))
    keep = (f >= lo) & (f <= hi)
    lo, hi = band
    shown = f"[{lo:g}, {hi:g}] {unit}"
    if not keep.any():
        raise DataError(f"{path!r}: no data point in band {shown} (the data span "
                        f"{f.min():g} to {f.max():g} {unit}); widen the band or check its unit")
    if below or above:
        warnings.warn(f"{path!r}: band {shown}: kept {int(keep.sum())} of {f.size} points "
                      f"(dropped {below} below {lo:g} {unit}, {above} above {hi:g} {unit})",
                      DataWarning, stacklevel=4)
    return keep


def _check_order(path, omega, lines, scale, unit):
    """DataError at the first frequency (``omega = scale * f``, rad/s) not above the one
    before, naming both file lines (``lines``, one per row) and ``f`` in ``unit``.

    A file out of order is refused, not sorted: it is often two sweeps appended (a
    segmented sweep, a repeated measurement), which sorting would interleave.
    """
    step = np.diff(omega)
    bad = np.flatnonzero(step <= 0)                     # NaN: left to FrequencyData
    if not bad.size:
        return
    k = int(bad[0]) + 1
    f0, f1 = omega[k - 1] / scale, omega[k] / scale
    head = f"{path!r} line {int(lines[k])}: frequency {f1:.10g} {unit}"
    if step[k - 1] == 0:
        raise DataError(f"{head} repeats the one on line {int(lines[k - 1])}; frequencies "
                        "must increase: remove one of the two rows (or, for two sweeps "
                        "appended, split the file into one file per sweep)")
    raise DataError(f"{head} follows {f0:.10g} {unit} on line {int(lines[k - 1])}; "
                    "frequencies must increase: sort the rows by frequency, or, if the file "
                    "holds two sweeps appended (or sweep segments that overlap), split it "
                    "into one file per sweep")


def _finish(path, omega, response, name, weights=None, lines=None, unit="rad/s", band=None,
            scale=1.0, file_unit="rad/s"):
    """Drop zero-frequency rows and reverse rows in descending frequency order (each stated
    by a DataWarning), refuse rows out of order or repeated (:func:`_check_order`), keep the
    points inside ``band`` (``(lo, hi)`` in the file's unit ``file_unit``, ``omega = scale
    * f``) and build the FrequencyData (frequency ``unit``); its errors are prefixed by the
    file name. ``lines`` are the file's line numbers of the rows, for messages."""
    omega = np.asarray(omega, float)
    rows = np.zeros(omega.size, int) if lines is None else np.asarray(lines)
    zero = omega == 0
    if zero.any():
        where = (f"line{'s' if zero.sum() > 1 else ''} "
                 f"{', '.join(str(lines[i]) for i in np.flatnonzero(zero)[:5])}"
                 if lines is not None else f"index {int(np.flatnonzero(zero)[0])}")
        warnings.warn(f"{path!r}: dropped {int(zero.sum())} row(s) at zero frequency ({where}): "
                      "the fit uses omega > 0 only (an integrator is a model option)",
                      DataWarning, stacklevel=3)
        keep = ~zero
        omega, response, rows = omega[keep], np.asarray(response)[keep], rows[keep]
        weights = None if weights is None else np.asarray(weights)[keep]
    if omega.size > 1 and np.all(np.diff(omega) < 0) and np.all(omega > 0):
        warnings.warn(f"{path!r}: the rows are in descending frequency order; read them in "
                      "ascending order", DataWarning, stacklevel=3)
        omega, response = omega[::-1], np.asarray(response)[::-1]
        weights = None if weights is None else np.asarray(weights)[::-1]
    elif lines is not None and np.all(omega > 0):        # else FrequencyData's message
        _check_order(path, omega, rows, scale, file_unit)
    if band is not None and omega.size:
        keep = _in_band(path, omega, band, scale, file_unit)
        omega, response = omega[keep], np.asarray(response)[keep]
        weights = None if weights is None else np.asarray(weights)[keep]
    try:
        return FrequencyData(omega, response, _stem(path) if name is None else name, weights,
                             unit)
    except DataError as exc:
        raise DataError(f"{path!r}: {exc}") from None

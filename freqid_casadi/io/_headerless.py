"""How a headerless table's columns are read without ``columns=`` (layer L1): by a
file-name convention (:data:`SUFFIX_COLUMNS`), and the check of the default reading as
frequency, real, imaginary (:func:`check_guessed`). Used by :mod:`._table`."""

import os
import warnings

import numpy as np

from ._columns import recognise
from ._readfile import DataWarning
from ..errors import DataError

__all__ = ["SUFFIX_COLUMNS", "suffix_columns", "check_guessed", "WRAP_JUMP"]

#: The columns of a headerless loudspeaker-measurement file, by suffix: ``.frd``
#: (frequency response data: Hz, SPL in dB, phase in degrees) and ``.zma`` (impedance: Hz,
#: ohms, degrees), as the loudspeaker tools write and read them.
SUFFIX_COLUMNS = {".frd": ("freq_hz", "mag_db", "phase_deg"),
                  ".zma": ("freq_hz", "mag", "phase_deg")}


def suffix_columns(path, n_cells):
    """The columns of a headerless file of ``n_cells`` columns that its suffix's convention
    gives (:data:`SUFFIX_COLUMNS`, stated by a DataWarning), or None.

    Parameters
    ----------
    path : str
        The file.
    n_cells : int

    Returns
    -------
    tuple of Column or None
    """
    suffix = os.path.splitext(str(path))[1].lower()
    if n_cells != 3 or suffix not in SUFFIX_COLUMNS:
        return None
    names = SUFFIX_COLUMNS[suffix]
    warnings.warn(f"{path!r}: no header: read as {', '.join(names)} (the {suffix} "
                  "convention); pass columns=... (command line --columns) otherwise",
                  DataWarning, stacklevel=6)
    return tuple(recognise(n) for n in names)


#: Least jump between neighbouring values of a headerless file's third column, all within
#: +-180, read as a phase in degrees wrapping (-177 to 178): an imaginary part does not
#: cross from near -180 to near +180 in one step.
WRAP_JUMP = 300.0


def check_guessed(path, values):
    """A headerless file read as frequency, real, imaginary: refuse a first column that
    counts the rows beside a second that increases like a frequency (an analyser's index,
    frequency, value: a Brüel & Kjær PULSE ASCII export), or a third column that wraps as
    a phase in degrees does (:data:`WRAP_JUMP`), else say how it was read.

    Parameters
    ----------
    path : str
    values : dict of str to ndarray
        The table's ``freq``, ``re`` and ``im`` columns.

    Raises
    ------
    DataError
        The first column is a row index, or the third a phase in degrees.
    """
    f, re_ = values["freq"], values["re"].real
    index = f.size > 2 and f[0] in (0.0, 1.0) and np.array_equal(f, f[0] + np.arange(f.size))
    if index and np.all(np.diff(re_) > 0) and re_[0] >= 0:
        raise DataError(f"{path!r}: the first column counts the rows ({f[0]:g}..{f[-1]:g}): "
                        "an index, not a frequency, and the second increases at every row "
                        "like a frequency; name the columns, e.g. columns='skip,freq_hz,re,im' "
                        "or 'skip,freq_hz,mag_db,phase_deg' (command line --columns); a "
                        "real-valued function (an autospectrum) has no phase to fit")
    im = values["im"].real
    wraps = np.flatnonzero(np.abs(np.diff(im)) > WRAP_JUMP) if im.size > 1 else []
    if len(wraps) and np.all(np.abs(im) <= 180.0 + 1e-9):
        k = int(wraps[0])
        raise DataError(f"{path!r}: no header, and the third column stays within +-180 and "
                        f"jumps from {im[k]:g} to {im[k + 1]:g} between data rows {k + 1} "
                        f"and {k + 2}, as a phase in degrees wraps: name the columns, e.g. "
                        "columns='freq_hz,mag_db,phase_deg' (or mag, phase_deg; command line "
                        "--columns); columns='f,re,im' reads them as real and imaginary "
                        "parts")
    warnings.warn(f"{path!r}: no header: read the columns as frequency, real, imaginary; if "
                  "they are magnitude and phase, pass columns='freq_hz,mag_db,phase_deg' "
                  "(or mag, phase_rad; command line --columns)", DataWarning, stacklevel=5)

"""File readers for frequency-response data (layer L1).

:func:`load` picks the reader by the file's extension: ``.npz`` :func:`load_npz`, ``.mat``
:func:`load_mat` (scipy.io), ``.uff``/``.unv`` :func:`load_uff` (UFF 58/58b via pyuff, extra
``[uff]``), Touchstone ``.sNp``/``.ts`` :func:`load_touchstone`, anything else
:func:`load_text` (CSV, semicolons, tabs or spaces).

Every reader returns a validated :class:`~freqid_casadi.core.data.FrequencyData` with ``omega``
in rad/s (``load_uff`` returns a tuple, one per record). Rows at zero frequency are dropped
and stated by a :class:`DataWarning` (the fit uses omega > 0; an integrator is a model
option). Every reader error is a :class:`~freqid_casadi.errors.DataError` naming the file,
the line and column where there is one, and the fix.

Bounded input: only regular files are read (a FIFO, a device or a folder is refused before
any read), at most :data:`MAX_FILE_BYTES` bytes, :data:`MAX_ROWS` data rows and
:data:`MAX_ELEMENTS` array elements (``.npz``/``.mat`` headers are checked before
allocating). Raise these module constants to read larger files.
"""

import io
import os
import re
import warnings
import zipfile

import numpy as np

from ._mat import (axis_variables, chosen_response, matrix_channels, read_mat_arrays,
                   records_hint, response_parts, spectrum_kind, start_step_axis)
from ._octave import is_octave_text
from ._touchstone import is_touchstone, load_touchstone
from ._traces import read_traces
from ._uff import load_uff, read_uff
from ._readfile import (MAX_ELEMENTS, MAX_FILE_BYTES, MAX_ROWS, DataWarning, _finish,
                        parse_band, read_regular_file)
from ._table import (Column, Table, _check_finite, _default_columns, _layout_problem,
                     _resolve_units, parse_columns, parse_freq_unit, read_table, recognise,
                     table_response)
from ..core.data import FrequencyData
from ..errors import DataError, OptionError

__all__ = ["load", "load_all", "is_uff", "is_mat", "load_text", "load_csv", "load_npz", "load_mat",
           "load_uff",
           "load_touchstone", "is_touchstone", "parse_band", "save_csv",
           "read_regular_file", "DataWarning", "MAX_FILE_BYTES", "MAX_ROWS", "MAX_ELEMENTS"]


_UFF_EXT = (".uff", ".unv", ".uf")


# --------------------------------------------------------------------------- dispatch

def load(path, name=None, *, freq_unit=None, columns=None, record=None, parameter=None,
         band=None):
    """Load frequency-response data from a file, the reader chosen by its extension.

    Parameters
    ----------
    path : str or path-like
        ``.npz`` (:func:`load_npz`), ``.mat`` (:func:`load_mat`), ``.uff``/``.unv``
        (:func:`load_uff`), Touchstone ``.s1p`` ... ``.sNp`` or ``.ts``
        (:func:`load_touchstone`), anything else delimited text (:func:`load_text`). A
        ``.json`` file is refused (a model file is read with ``RationalDelayModel.load``).
    name : str, optional
        Name of the data (default: the file's stem).
    freq_unit : {"Hz", "rad/s"}, optional
        Unit of the frequency column when the file does not say it (a headerless text file,
        a header ``f``/``freq``); also accepted when the file says the same. Case-insensitive.
    columns : str or sequence of str, optional
        Names of the columns of a text file or of a ``.mat`` matrix, e.g. ``"f,re,im"`` or
        ``("freq_hz", "mag_db", "phase_deg")``, or of the frequency and the two traces of
        an analyser's export of trace blocks; see :func:`load_text`.
    record : int, optional
        For a UFF file with several frequency-response records: which one (0-based,
        counting the records :func:`load_uff` returns: records that are not frequency
        responses are skipped). For LTspice's text export of an AC analysis with ``.step``
        runs: which run (:func:`load_text`).
    parameter : str, optional
        For a Touchstone file (``.sNp`` of any number of ports, or a Touchstone 2.0
        ``.ts``): which parameter (default S11), e.g. "S21". For a text table whose
        header names S-parameters (a network analyser's CSV: ``S21(REAL)``, ``S21(IMAG)``,
        ``S11(REAL)``, ...) or receiver ratios (``A2/A1(REAL)``): which one to read (see
        :func:`load_text`).
    band : (float, float), optional
        Keep only the points with ``lo <= f <= hi``, in the file's frequency unit (Hz for a
        header ``Frequency (Hz)`` or a unit line ``Hz``, rad/s for ``omega``, the option
        line's unit for Touchstone); a DataWarning says how many were dropped.

    Returns
    -------
    FrequencyData
        Always one data set (a UFF file with several records needs ``record=``, or
        :func:`load_uff` for all of them).

    Raises
    ------
    DataError
        Anything wrong with the file, naming the file, line, column and fix.
    OptionError
        An invalid ``freq_unit`` or ``columns``; ``record``, ``parameter`` or ``columns``
        given for a kind of file they do not apply to (:func:`refuse_options`).

    Warns
    -----
    DataWarning
        Rows at zero frequency were dropped.
    """
    freq_unit = parse_freq_unit(freq_unit)
    cols = parse_columns(columns)
    band = parse_band(band)
    lower = os.fspath(path).lower() if isinstance(path, (str, os.PathLike)) else ""
    refuse_options(path, record=record, parameter=parameter, columns=cols)
    if lower.endswith(".npz"):
        return load_npz(path, name, freq_unit=freq_unit, band=band)
    if is_touchstone(lower):
        if freq_unit is not None or cols is not None:
            raise OptionError("freq_unit and columns do not apply to Touchstone files (the "
                              "option line gives the units); drop them")
        return load_touchstone(path, name, parameter=parameter, band=band)
    if is_mat(path):
        return load_mat(path, name, freq_unit=freq_unit, columns=cols, band=band,
                        parameter=parameter)
    if lower.endswith(".json"):
        raise DataError(f"{os.fspath(path)!r} is JSON, not frequency-response data: a model "
                        "file that freqid wrote (model.json) is read with "
                        "freqid_casadi.RationalDelayModel.load(path); data files are text "
                        "(CSV), .npz, .mat, .uff/.unv or Touchstone .sNp/.ts")
    if is_uff(path):
        if cols is not None or parameter is not None:
            raise OptionError(f"{os.fspath(path)!r} is a universal file (UFF): its records "
                              "name their own units and values; drop columns= and parameter= "
                              "(--columns, --parameter)")
        count, found = read_uff(path, freq_unit=freq_unit, band=band, record=record,
                                single=True)
        if not found:
            raise DataError(
                f"{os.fspath(path)!r} holds {count} frequency-response records: pass "
                f"record=0..{count - 1} to load() (command line --record K; freqid modal "
                "reads them all), or use load_uff() for all of them")
        data = found[0]
        return data if name is None else FrequencyData(data.omega, data.response, name)
    return load_text(path, name, freq_unit=freq_unit, columns=cols, band=band,
                     parameter=parameter, record=record)


def load_all(path, *, freq_unit=None, columns=None, band=None):
    """Every frequency response a file holds, one data set each (the channels of a modal
    test, for :func:`freqid_casadi.fit_shared`).

    Parameters
    ----------
    path : str or path-like
        A UFF file gives each frequency-response record (:func:`load_uff`); a ``.mat`` file
        each complex response beside its frequency vector: every channel of an FRF matrix
        (``H``, N x 9, named ``H(:,1)`` ... ``H(:,9)``; MATLAB ``modalfrf``'s ``frf``, N x
        outputs x inputs, ``frf(:,2,1)``) and each complex vector (``H21``, ``H22``). Any
        other file gives the one response :func:`load` reads (a Touchstone file's chosen
        parameter: ``load(path, parameter="S21")``).
    freq_unit, columns, band
        As for :func:`load`.

    Returns
    -------
    list of FrequencyData
        In the file's order, each named by its record (UFF) or MATLAB name (``.mat``);
        ``omega`` in rad/s.

    Raises
    ------
    DataError, OptionError
        As :func:`load`.
    """
    freq_unit = parse_freq_unit(freq_unit)
    band = parse_band(band)
    lower = os.fspath(path).lower() if isinstance(path, (str, os.PathLike)) else ""
    if is_mat(path):
        return _mat_all(path, freq_unit, columns, band)
    plain = lower.endswith((".npz", ".json")) or is_touchstone(lower)
    if not plain and is_uff(path):
        if parse_columns(columns) is not None:
            raise OptionError(f"{os.fspath(path)!r} is a universal file (UFF): its records "
                              "name their own units and values; drop columns= (--columns)")
        return list(load_uff(path, freq_unit=freq_unit, band=band))
    return [load(path, freq_unit=freq_unit, columns=columns, band=band)]


def is_mat(path):
    """Whether ``path`` is read as a MATLAB file: a ``.mat`` name, or a regular file of
    another name that begins as GNU Octave's text format (``# Created by Octave``, or
    ``# name:`` and ``# type:`` lines), which Octave's ``save`` writes by default.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    bool
    """
    if not isinstance(path, (str, os.PathLike)):
        return False
    if os.fspath(path).lower().endswith(".mat"):
        return True
    try:
        if not os.path.isfile(path):     # a FIFO or a device is not opened (it may block)
            return False
        with open(path, "rb") as fh:
            return is_octave_text(fh.read(400))
    except OSError:
        return False


def is_uff(path):
    """Whether ``path`` is read as a universal file: a ``.uff``/``.unv`` name, or a regular
    file that begins as one (:func:`_looks_like_uff`).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    bool
    """
    lower = os.fspath(path).lower() if isinstance(path, (str, os.PathLike)) else ""
    return lower.endswith(_UFF_EXT) or _looks_like_uff(path)


def _looks_like_uff(path):
    """Whether a file of another extension begins as a universal file does (a ``-1``
    line, then a dataset number such as ``58`` or ``58b``): analysers name their UFF
    exports ``.frf``, ``.ufd``, ``.asc``, ... and the binary ones hold NUL bytes a text
    reader refuses."""
    try:
        if not os.path.isfile(path):     # a FIFO or a device is not opened (it may block)
            return False
        with open(path, "rb") as fh:
            head = fh.read(512).decode("latin-1")
    except (OSError, TypeError, ValueError):
        return False                     # the reader names the problem
    lines = [line.strip() for line in head.splitlines() if line.strip()]
    return len(lines) >= 2 and lines[0] == "-1" and re.match(r"\d+b?(\s|$)", lines[1]) \
        is not None


def refuse_options(path, *, record=None, parameter=None, columns=None, flag=False):
    """Refuse an option given to :func:`load` for a kind of file it does not apply to
    (it would be ignored): ``record`` of a .npz, .mat or Touchstone file (it chooses a UFF
    record or an LTspice run), ``parameter`` of a .npz, .mat or UFF file (it chooses a
    Touchstone or text table's S-parameter), ``columns`` of a .npz or UFF file.

    Parameters
    ----------
    path : str or path-like
    record, parameter, columns : optional
        The options as given (None: not given).
    flag : bool, optional
        Name the options as the command line spells them (``--record``).

    Raises
    ------
    OptionError
        An option that does not apply, with what it chooses and "drop it".
    """
    lower = os.fspath(path).lower() if isinstance(path, (str, os.PathLike)) else ""
    spell = (lambda k: f"--{k}") if flag else (lambda k: f"{k}=")
    if record is not None and (lower.endswith(".npz") or is_mat(path)
                               or is_touchstone(lower)):
        raise OptionError(f"{spell('record')} chooses a record of a UFF file (.uff/.unv) or "
                          f"a run of an LTspice export with .step runs, not of {path!r}; "
                          "drop it")
    if parameter is not None and lower.endswith((".npz",) + _UFF_EXT):
        raise OptionError(f"{spell('parameter')} chooses a parameter of a Touchstone file "
                          "(.s1p, .s2p, ..., .sNp, .ts), of a text table whose header "
                          "names S-parameters or the response variable of a .mat file, not "
                          f"of {path!r}; drop it")
    if columns is not None and lower.endswith((".npz",) + _UFF_EXT):
        raise OptionError(f"{spell('columns')} names the columns of a text table or a .mat "
                          f"matrix; {path!r} names its own arrays or records: drop it")


def load_text(path, name=None, *, freq_unit=None, columns=None, band=None, parameter=None,
              record=None):
    """Read frequency-response data from delimited text.

    Parameters
    ----------
    path : str or path-like
        Text in UTF-8 (a leading byte-order mark is accepted), UTF-16 with a byte-order
        mark, the encoding the file declares (``# encoding: ...``), else Windows-1252 /
        Latin-1 (a fallback is stated by a DataWarning). Separator: semicolon, tab, comma
        or whitespace, taken from the data rows; decimal commas in a file separated by
        semicolons, tabs or spaces without decimal points. Lines starting with ``#``, ``%``,
        ``!`` or ``*`` (Room EQ Wizard) and blank lines are skipped; metadata lines before
        the header (an analyser's preamble) are skipped with a DataWarning.
    name : str, optional
        Name of the data (default: the file's stem).
    freq_unit : {"Hz", "rad/s"}, optional
        Unit of the frequency column when the file does not give it.
    columns : str or sequence of str, optional
        One name per column, overriding a header (which is then skipped). Names
        (case-insensitive; a unit may follow in brackets, ``"f [Hz]"``, or as a suffix,
        ``freq_hz``):

        - frequency: ``omega``, ``w`` (rad/s); ``f_hz``, ``freq_hz``, ``hz`` (Hz);
          ``f``, ``freq``, ``frequency`` (unit from ``freq_unit``);
        - ``re``/``real`` with ``im``/``imag``; ``mag`` (linear) or ``mag_db``/``db`` with
          ``phase_deg`` or ``phase_rad``; or one complex column ``complex``/``response``/
          ``h``/``g`` holding literals ``1+2j``, ``(1+2j)`` or ``1+2i``;
        - ``skip`` for a column to ignore.
    band : (float, float), optional
        Keep only the rows with ``lo <= f <= hi`` in the file's frequency unit.
    parameter : str, optional
        The S-parameter to read from a header that names several (``"S21"`` of a network
        analyser's ``Freq(Hz),S21(REAL),S21(IMAG),S11(REAL),...``; ``S21(DB)``,
        ``S21 Log Mag(dB)``, ``S21 Phase(deg)`` are read too), or a receiver ratio
        (``"A2/A1"`` of ``A2/A1(REAL)``, ``"B/R1"``); the other responses' columns are
        skipped.
    record : int, optional
        For LTspice's export of an AC analysis with ``.step`` runs (a ``Step Information:``
        line before each): which run (0-based); required when there are several.

    Returns
    -------
    FrequencyData
        The data rows (``omega`` in rad/s, rows at zero frequency dropped), named
        ``name`` or the file's stem.

    Raises
    ------
    DataError
        Binary (NUL bytes), empty, no data rows, unknown header, a headerless file without
        ``freq_unit``, wrong column count, a cell that is not an ASCII decimal number
        (``1_0`` and non-ASCII digits are refused), non-finite values, dB values that
        overflow, negative or unsorted frequencies, zero responses.
    OptionError
        ``parameter`` is not one of the S-parameters the header names; ``record`` is out of
        range or the file has no runs.

    Notes
    -----
    A header is recognised when the first line holds a cell that is not a number; a second
    line of units only (``Hz  dB  deg``) completes it. Above the data (the first three rows
    of numbers) the nearest line that names every column is the header; the lines before
    it are a preamble (``Units: Ratio``, channel lines, as SignalCalc exports) and a line
    between it and the data whose first word is a frequency unit (``Hz  (m/s²)(N)``) gives
    the units; headerless data take the last non-empty comment line before them as
    header when it names every column (``% f [Hz]  Re  Im``, ``* Freq(Hz) SPL(dB)
    Phase(degrees)``). Decimal commas are read in a semicolon-, tab- or space-separated
    file without decimal points; rows in descending frequency order are reversed (with a
    :class:`DataWarning`). Header
    ``omega,real,imag`` and ``omega,magnitude_db,phase_deg`` are the layouts
    :func:`save_csv` and earlier versions wrote. A headerless file with three columns is
    frequency, real, imaginary; with two columns of which the second holds complex
    literals, frequency and response.

    An HP/Agilent impedance or network analyser's ASCII save of trace blocks (the 4294A's
    ``"TRACE: A"`` ... ``"Frequency"  "Data Trace Real"  "Data Trace Imag"``, frequencies
    in Hz) is read as one response: two scalar traces as magnitude and phase or real and
    imaginary part, as the file's measure parameter (``IMPEDANCE MAG PHASE (DEG)``,
    ``R-X``) or the traces' ``FORMAT`` lines (``LOG MAG``, ``PHASE``) say, or else as
    ``columns`` names the frequency and each trace in order (``"freq_hz,mag,phase_deg"``);
    one complex trace as its Real and Imag columns. Traces of different frequencies are
    refused; a DataWarning says which trace was read as what.
    """
    band = parse_band(band)
    path, payload = read_regular_file(path)
    columns, freq_unit = parse_columns(columns), parse_freq_unit(freq_unit)
    table = read_traces(path, payload, columns, freq_unit, parameter=parameter, record=record)
    if table is None:
        table = read_table(path, payload, columns, freq_unit, max_rows=MAX_ROWS,
                           parameter=parameter, record=record)
    omega, response = table_response(table)
    unit = "rad/sample" if table.unit("freq") == "rad/sample" else "rad/s"
    return _finish(path, omega, response, name, lines=table.lines, unit=unit, band=band,
                   **_band_unit(table.unit("freq")))


def _band_unit(unit):
    """``scale`` and ``file_unit`` keywords of ``_finish`` for a table's frequency unit."""
    return ({"scale": 2 * np.pi, "file_unit": "Hz"} if unit == "hz" else
            {"scale": 1.0, "file_unit": unit})


def load_csv(path, name=None, *, freq_unit=None, columns=None, band=None):
    """Read a CSV (or any delimited text) file: the same as :func:`load_text`.

    Parameters
    ----------
    path : str or os.PathLike
    name : str, optional
    freq_unit : {"hz", "rad/s"}, optional
    columns : str or sequence of str, optional
        As :func:`load_text`.
    band : (float, float), optional
        As :func:`load_text`.
    """
    return load_text(path, name, freq_unit=freq_unit, columns=columns, band=band)


# --------------------------------------------------------------------------- npz

_SAVEZ = "np.savez(path, omega=omega, response=response)"


def _npz_headers(path, payload):
    """Shape and dtype of every member, read from the .npy headers before any allocation."""
    found = {}
    with zipfile.ZipFile(io.BytesIO(payload)) as zf:
        for info in zf.infolist():
            key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            with zf.open(info) as fh:
                version = np.lib.format.read_magic(fh)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
                else:
                    shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
            n = 1
            for d in shape:
                n *= int(d)
            if n > MAX_ELEMENTS:
                raise DataError(
                    f"{path!r}: array {key!r} claims shape {shape} ({n} elements), above the "
                    f"limit of {MAX_ELEMENTS} (freqid_casadi.io.loaders.MAX_ELEMENTS); the file "
                    "is damaged or not frequency-response data")
            if n * dtype.itemsize > info.file_size:
                raise DataError(f"{path!r}: array {key!r} is truncated (its header claims "
                                f"{n} elements of {dtype}); save the file again with {_SAVEZ}")
            found[key] = (shape, dtype)
    return found


def _check_dtype(path, key, dtype, complex_ok):
    unit = " (rad/s)" if key == "omega" else ""
    if dtype.kind == "c" and not complex_ok:
        raise DataError(f"{path!r}: array {key!r} has dtype {dtype}: {key} must be real{unit}; "
                        f"save it as floats with {_SAVEZ}")
    if dtype.kind not in "iufc":
        what = "datetimes" if dtype.kind in "Mm" else f"dtype {dtype}"
        raise DataError(f"{path!r}: array {key!r} holds {what}: {key} must be an array of "
                        f"numbers{unit}; save plain floats with {_SAVEZ}")


def load_npz(path, name=None, *, freq_unit=None, band=None):
    """Read data from a NumPy ``.npz`` archive.

    Parameters
    ----------
    path : str or path-like
        Arrays ``omega`` (rad/s; or ``freq_hz`` in Hz), ``response`` (complex) and
        optionally ``weights``.
    name : str, optional
    freq_unit : {"Hz", "rad/s"}, optional
        Unit of the array ``omega`` when it is not in rad/s ("Hz": multiplied by 2 pi).
    band : (float, float), optional
        Keep only the points with ``lo <= f <= hi`` (Hz for ``freq_hz`` or
        ``freq_unit="Hz"``, else rad/s).

    Returns
    -------
    FrequencyData
        The arrays ``omega`` (in rad/s), ``response`` and ``weights`` (if the archive
        holds it), named ``name`` or the file's stem.

    Raises
    ------
    DataError
        A file that is not an .npz archive (or is a single-array .npy), missing arrays,
        headers claiming more than :data:`MAX_ELEMENTS` elements (checked before reading
        the data), non-numeric or datetime dtypes, and any violation of FrequencyData.
    """
    freq_unit = parse_freq_unit(freq_unit)
    band = parse_band(band)
    path, payload = read_regular_file(path)
    if payload.startswith(b"\x93NUMPY"):
        raise DataError(f"{path!r} holds a single array (.npy), not an .npz archive; save "
                        f"with {_SAVEZ}")
    try:
        headers = _npz_headers(path, payload)
        keys = set(headers)
        freq_key = "omega" if "omega" in keys or "freq_hz" not in keys else "freq_hz"
        missing = {freq_key, "response"} - keys
        if missing:
            raise DataError(f"{path!r} lacks array(s) {sorted(missing)}; save with {_SAVEZ}")
        for key, complex_ok in ((freq_key, False), ("response", True), ("weights", False)):
            if key in headers:
                _check_dtype(path, key, headers[key][1], complex_ok)
        with np.load(io.BytesIO(payload), allow_pickle=False) as npz:
            omega, response = npz[freq_key], npz["response"]
            weights = npz["weights"] if "weights" in keys else None
    except DataError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile) as exc:
        raise DataError(f"cannot read {path!r} as .npz ({exc}); save it with {_SAVEZ}") \
            from None
    if freq_key == "freq_hz" and freq_unit == "rad/s":
        raise DataError(f"{path!r}: array 'freq_hz' is in Hz, but freq_unit='rad/s'; drop "
                        "freq_unit or rename the array")
    hz = freq_key == "freq_hz" or freq_unit == "hz"
    if hz:
        omega = 2 * np.pi * np.asarray(omega, float)
    return _finish(path, omega, response, name, weights, band=band,
                   **_band_unit("hz" if hz else "rad/s"))


# --------------------------------------------------------------------------- mat

def load_mat(path, name=None, *, freq_unit=None, columns=None, band=None, parameter=None):
    """Read data from a MATLAB ``.mat`` file (v4 to v7.2, via ``scipy.io.loadmat``).

    Parameters
    ----------
    path : str or path-like
    name : str, optional
    freq_unit : {"Hz", "rad/s"}, optional
        As for :func:`load_text`.
    columns : str or sequence of str, optional
        Names of the columns of the single numeric matrix (N x k, or k x N) the file holds.
    band : (float, float), optional
        As :func:`load_text`.
    parameter : str, optional
        The variable that holds the response, for a file of several (``"H21"`` beside
        ``H22`` and one frequency axis): a complex vector, or a real N x 2 matrix of real
        and imaginary parts; the frequency variables are read as without it.

    Returns
    -------
    FrequencyData
        The matched variables or matrix columns (``omega`` in rad/s), named ``name`` or
        the file's stem.

    Raises
    ------
    DataError
        Not a MATLAB file, v7.3 (HDF5), arrays above :data:`MAX_ELEMENTS` (from the
        headers, before reading), no recognisable variables, bad values.

    Notes
    -----
    Variables, and the fields of structs (``frf.freq_hz``, ``frf.response``), are matched
    by name with the vocabulary of :func:`load_text` (``omega``, ``w``, ``freq_hz``, ``f`` +
    ``freq_unit``; ``response``/``h``/``g``/``frf`` complex, ``re``/``im``,
    ``mag_db``/``phase_deg``, ...). Without such names, a single numeric matrix is read like
    a headerless text table (``columns`` names its columns). A file of time records (two or
    more real vectors of one length) is refused with the command that reads it:
    ``freqid frf FILE --u NAME --y NAME``
    (:func:`freqid_casadi.experiment.load_records_mat`).

    The frequency axis may also be given by scalars beside the response: a start and a step
    (``f_start`` and ``df``, ``f0`` and ``df``, ``fstart`` and ``fstep``, ``freq_start``
    and ``delta_f``; ``w0`` and ``dw`` in rad/s), ``f[k] = start + k step`` for the
    response's N points, or a start and an end (``fstart``, ``fend``: N points from one
    to the other); an end or a count (``nf``, ``n_points``) beside a step is checked. Their
    unit is decided as for a frequency vector: ``f_start_hz``/``df_hz`` are Hz, ``w0``/``dw``
    rad/s, ``f_start``/``df`` take ``freq_unit``. Beside such an axis, one array of any
    name is the response: a complex vector, or a real N x 2 matrix read as real and
    imaginary parts (with a DataWarning).
    """
    freq_unit = parse_freq_unit(freq_unit)
    columns = parse_columns(columns)
    band = parse_band(band)
    path, payload = read_regular_file(path)
    arrays = read_mat_arrays(path, payload, MAX_ELEMENTS)
    n, alias = _freq_axis(arrays)
    return _mat_data(path, arrays, matrix_channels(arrays, n), alias, parameter, columns,
                     freq_unit, band, name)


def _mat_data(path, arrays, channels, alias, parameter, columns, freq_unit, band, name):
    """The one response of a ``.mat`` file's ``arrays`` that :func:`load_mat` reads
    (``parameter`` chooses among ``arrays`` and the matrix ``channels``; ``alias``: see
    :func:`_freq_axis`)."""
    if parameter is None:
        parameter = _beside_spectra(path, arrays, alias)
    if parameter is not None:
        arrays = chosen_response(path, {**arrays, **channels}, str(parameter),
                                 _freq_names(alias))
    try:
        table = _mat_table(path, arrays, columns, freq_unit, alias)
    except DataError:
        if channels and parameter is None and columns is None:
            raise DataError(_several_channels(path, arrays, channels)) from None
        raise
    omega, response = table_response(table)
    return _finish(path, omega, response, name, band=band, **_band_unit(table.unit("freq")))


def _complex_vectors(arrays, alias):
    """The complex vectors of a ``.mat`` file as long as its frequency vector (any length
    when it has none), in file order."""
    n = _freq_axis(arrays)[0] if alias is None else np.size(arrays[alias])
    return [k for k, a in arrays.items() if np.iscomplexobj(a) and np.ndim(a) == 1
            and np.size(a) > 1 and (not n or np.size(a) == n)]


def _beside_spectra(path, arrays, alias):
    """The one complex vector of a ``.mat`` file whose name does not say it is a spectrum
    (:func:`spectrum_kind`) when every other one is (an analyser's ``Hf_chan_2`` beside
    ``Hf_Cross_Spec_chan_2``), noted; else None (the file is read as it names itself)."""
    found = _complex_vectors(arrays, alias)
    spectra = [k for k in found if spectrum_kind(k)]
    if not spectra or len(found) - len(spectra) != 1:
        return None
    key = next(k for k in found if k not in spectra)
    warnings.warn(f"{path!r}: read {key} as the response; not read: "
                  f"{_spectra_words(spectra)}", DataWarning, stacklevel=5)
    return key


def _spectra_words(names):
    """``'Gxy (a cross-spectrum), coh (a coherence)'``."""
    return ", ".join(f"{k} (a {spectrum_kind(k)})" for k in names)


def _mat_all(path, freq_unit, columns, band):
    """Every response of a ``.mat`` file beside its frequency axis (:func:`load_all`):
    complex vectors and matrix channels, else real N x 2 matrices of real and imaginary
    parts; the file's one response, as :func:`load_mat` reads it, when it holds fewer
    than two."""
    columns = parse_columns(columns)
    where, payload = read_regular_file(path)
    arrays = read_mat_arrays(where, payload, MAX_ELEMENTS)
    n, alias = _freq_axis(arrays)
    one = (where, arrays, matrix_channels(arrays, n), alias)      # as load_mat reads it
    if not n and axis_variables(arrays):            # an axis of start and step: the
        sizes = {_response_length(a) for a in arrays.values()}   # responses' length
        sizes.discard(0)
        n = sizes.pop() if len(sizes) == 1 else 0
    channels = matrix_channels(arrays, n) if n else {}
    names = [k for k, a in arrays.items()
             if np.ndim(a) == 1 and np.size(a) == n and np.iscomplexobj(a)] + list(channels)
    if not names:                                   # real and imaginary parts, N x 2
        names = [k for k, a in arrays.items() if k != alias and not _is_freq(k)
                 and not np.iscomplexobj(a) and _response_length(a) == n]
    spectra = [k for k in names if spectrum_kind(k)]
    kept = [k for k in names if k not in spectra]
    if spectra and kept:
        if len(kept) >= 2:                       # (one: load_mat reads it, with its note)
            warnings.warn(f"{where!r}: not read: {_spectra_words(spectra)}", DataWarning,
                          stacklevel=3)
        names = kept
    if columns is not None or not n or len(names) < 2:
        return [_mat_data(*one, None, columns, freq_unit, band, None)]
    return [_mat_data(where, arrays, channels, alias, key, None, freq_unit, band, key)
            for key in names]


def _response_length(array):
    """The points of an array read as a response (a complex vector, or a real N x 2
    matrix of real and imaginary parts), else 0."""
    shape = np.shape(array)
    if np.iscomplexobj(array) and len(shape) == 1 and shape[0] > 1:
        return shape[0]
    if not np.iscomplexobj(array) and len(shape) == 2 and 2 in shape and max(shape) > 2:
        return max(shape)
    return 0


#: Words (lower case, anywhere in a variable's name) of a frequency vector the reader's
#: vocabulary does not know (``freqs``, ``frequencyBand``, ``FreqAxis``), taken for the
#: axis when it is the file's only such vector, increasing, as long as a response.
_AXIS_WORDS = ("freq", "omega")


def _freq_axis(arrays):
    """``(n, alias)``: the length of a ``.mat`` file's frequency vectors (real vectors
    named as one) and None; else, when one real increasing vector named like one
    (:data:`_AXIS_WORDS`) is as long as a response or a complex matrix's dimension, its
    length and name; else ``(0, None)``."""
    sizes = {np.size(a) for k, a in arrays.items() if np.ndim(a) == 1 and np.size(a) > 1
             and not np.iscomplexobj(a) and _is_freq(k)}
    if sizes:
        return (sizes.pop(), None) if len(sizes) == 1 else (0, None)
    dims = {d for a in arrays.values() if np.iscomplexobj(a) for d in np.shape(a)}
    dims |= {_response_length(a) for a in arrays.values()}
    found = [k for k, a in arrays.items()
             if np.ndim(a) == 1 and np.size(a) in dims and np.size(a) > 1
             and not np.iscomplexobj(a)
             and any(w in k.rsplit(".", 1)[-1].lower() for w in _AXIS_WORDS)
             and np.all(np.diff(np.asarray(a, float)) > 0)]
    return (np.size(arrays[found[0]]), found[0]) if len(found) == 1 else (0, None)


def _freq_names(alias):
    """``name -> bool``: the names the reader takes for a frequency vector, and ``alias``."""
    return _is_freq if alias is None else (lambda key: key == alias or _is_freq(key))


def _several_channels(path, arrays, channels):
    """The message for a ``.mat`` file whose response is a matrix of several channels."""
    keys = list(channels)
    matrices = sorted({k.split("(", 1)[0] for k in keys}, key=list(arrays).index)
    shown = ", ".join(f"{m} ({' x '.join(map(str, np.shape(arrays[m])))})" for m in matrices)
    return (f"{path!r} holds {len(keys)} responses ({shown}: one per channel beside the "
            f"frequencies), not one: choose one with parameter='{keys[0]}' ... "
            f"'{keys[-1]}' (command line --parameter '{keys[0]}'), or read them all with "
            "freqid_casadi.load_all (freqid modal reads them all, one channel each)")


# --------------------------------------------------------------------------- .mat

def _mat_table(path, arrays, columns, freq_unit, alias=None):
    """A :class:`Table` from the numeric variables of a ``.mat`` file (see
    ``loaders.load_mat``); ``alias`` names a frequency vector outside the vocabulary
    (:func:`_freq_axis`)."""
    named = {}
    if columns is None:
        for key, arr in arrays.items():
            col = recognise(key.rsplit(".", 1)[-1])
            if key == alias:
                col = Column("freq", _alias_unit(key), key)
            if col is not None and col.role != "skip":
                named[key] = Column(col.role, col.unit, key)
    cols = tuple(named.values())
    if named and _layout_problem(cols) is not None and \
            _layout_problem(cols + (Column("freq"),)) is None and \
            all(np.ndim(arrays[k]) <= 1 or 1 in np.shape(arrays[k]) for k in named):
        # a response without a frequency vector: an axis of start and step beside it?
        values, n = _mat_vectors(path, arrays, named)
        axis = start_step_axis(path, arrays, n, freq_unit)
        if axis is None:
            raise DataError(_no_axis(path, arrays, named))
        values["freq"] = axis[0]
        cols += (Column("freq", axis[1], axis[2]),)
    elif named and _layout_problem(cols) is None:
        values, n = _mat_vectors(path, arrays, named)
    elif columns is None and not named and axis_variables(arrays):
        cols, values, n = _beside_axis(path, arrays)
        axis = start_step_axis(path, arrays, n, freq_unit)
        values["freq"] = axis[0]
        cols += (Column("freq", axis[1], axis[2]),)
    else:
        cols, values, n = _mat_matrix(path, arrays, columns, named)
    freq = next((c for c in cols if c.role == "freq"), None)
    if named and freq is not None and freq.unit is None and freq_unit is None:
        raise DataError(f"{path!r}: the unit of the frequency variable {freq.label} is "
                        "unknown: pass freq_unit='Hz' or freq_unit='rad/s' (command line "
                        "--freq-unit hz|rad/s), or save it as freq_hz (Hz) or omega (rad/s)")
    cols = _resolve_units(path, cols, freq_unit, ",".join(named) if named else None)
    for k, arr in values.items():
        values[k] = np.asarray(arr, complex if k == "complex" else float)
    table = Table(path, cols, values, np.arange(1, n + 1), where="row")
    _check_finite(table)
    return table


def _alias_unit(name):
    """The unit a frequency variable's name outside the vocabulary states (``freq_hz_axis``,
    ``omega_vec``), or None."""
    low = name.rsplit(".", 1)[-1].lower()
    return "hz" if "hz" in low else "rad/s" if "omega" in low or "rad" in low else None


def _is_freq(name):
    col = recognise(name.rsplit(".", 1)[-1])
    return col is not None and col.role == "freq"


def _mat_vectors(path, arrays, named):
    """``({role: vector}, length)`` of the variables ``named`` (name: Column), which must be
    vectors of one length."""
    vecs = [np.asarray(arrays[k]).reshape(-1) if 1 in np.shape(arrays[k]) or
            np.ndim(arrays[k]) <= 1 else None for k in named]
    if any(v is None for v in vecs) or len({v.size for v in vecs}) != 1:
        raise DataError(f"{path!r}: variables {', '.join(named)} must be vectors of equal "
                        "length")
    return dict(zip((c.role for c in named.values()), vecs)), vecs[0].size


def _no_frequencies(arrays):
    """Whether a ``.mat`` file's arrays are complex matrices (more than 3 columns, or
    several of them) and no real vector could be their frequency axis."""
    complex_ = [a for a in arrays.values() if np.iscomplexobj(a) and np.ndim(a) >= 2]
    real = [a for a in arrays.values() if not np.iscomplexobj(a) and np.size(a) > 1]
    if not complex_ or real:
        return False
    return len(complex_) > 1 or min(np.shape(complex_[0])) > 3


def _found(arrays):
    """``'frf (512, complex), df (scalar)'``: the variables of a .mat file, for a message."""
    return ", ".join(f"{k} ({' x '.join(map(str, np.shape(a))) or 'scalar'}"
                     f"{', complex' if np.iscomplexobj(a) else ''})" for k, a in arrays.items())


def _no_axis(path, arrays, named):
    """The message for a .mat file whose response (the variables ``named``) has no
    frequency axis beside it."""
    return (f"{path!r} holds a response ({', '.join(named)}) but no frequency axis (found "
            f"{_found(arrays)}): save the frequencies beside it as freq_hz (Hz) or omega "
            "(rad/s) (or f with freq_unit='Hz', command line --freq-unit hz), or their start "
            "and step as scalars f_start and df (the count is the response's length; "
            "f_start_hz and df_hz say Hz, else pass freq_unit); or build the data in "
            "Python: freqid_casadi.FrequencyData(omega, response)")


def _beside_axis(path, arrays):
    """``(columns, {role: vector}, length)`` of the one array beside the scalars of a
    frequency axis (``f_start``, ``df``) whose name is not one the reader knows: a complex
    vector is the response, a real N x 2 matrix its real and imaginary parts (as a
    headerless table's columns are read, stated by a DataWarning)."""
    axis = axis_variables(arrays)
    rest = {k: a for k, a in arrays.items() if k not in axis}
    key = next(iter(rest)) if rest else None
    parts = response_parts(path, key, rest[key], stacklevel=6) if len(rest) == 1 else None
    if parts is not None and "complex" in parts:
        return (Column("complex", None, key),), parts, parts["complex"].size
    if parts is not None:
        return ((Column("re", None, f"{key}(:, 1)"), Column("im", None, f"{key}(:, 2)")),
                parts, parts["re"].size)
    hint = records_hint(path, rest)
    if hint:
        raise DataError(hint)
    raise DataError(
        f"{path!r} gives a frequency axis ({', '.join(axis)}) beside "
        f"{len(rest)} other arrays, not one response (found {_found(arrays)}): choose the "
        f"response with parameter='{next(iter(rest))}' (command line --parameter "
        f"{next(iter(rest))})")


def _mat_matrix(path, arrays, columns, named):
    """``(columns, {role: vector}, rows)`` of the single N x k matrix of a .mat file,
    read like a headerless text table (``columns`` names its columns)."""
    hint = records_hint(path, arrays) if columns is None and not named else None
    if hint:
        raise DataError(hint)
    if columns is None and _no_frequencies(arrays):
        raise DataError(
            f"{path!r} holds complex responses but no frequency variable (found "
            f"{_found(arrays)}): save the frequencies beside them as freq_hz (Hz) or omega "
            "(rad/s), a vector as long as the responses (or f with freq_unit='Hz', "
            "command line --freq-unit hz), or their start and step as scalars f_start and "
            "df")
    if len(arrays) != 1 or np.ndim(next(iter(arrays.values()))) != 2:
        hint = records_hint(path, arrays) if columns is None else None
        if hint:
            raise DataError(hint)
        found = _complex_vectors(arrays, None)
        if columns is None and len(found) >= 2:
            first = next((k for k in found if not spectrum_kind(k)), found[0])
            shown = ", ".join(f"{k} (a {spectrum_kind(k)})" if spectrum_kind(k) else k
                              for k in found)
            raise DataError(
                f"{path!r} holds {len(found)} complex vectors ({shown}), not one response: "
                f"choose the response with parameter='{first}' (command line --parameter "
                f"{first}), or read every one with freqid_casadi.load_all (freqid modal "
                f"reads them all, one channel each); the file holds {_found(arrays)}")
        raise DataError(
            f"{path!r}: cannot tell the variables apart (found {_found(arrays)}); name them "
            "omega (rad/s) or freq_hz (Hz) and response (complex), or save one N x k "
            "matrix and pass columns=...; for one channel of an FRF matrix, in MATLAB: "
            "freq_hz = <frequencies>; response = <matrix>(:, k); save('frf_k.mat', "
            "'freq_hz', 'response', '-v7')")
    mat = np.asarray(next(iter(arrays.values())))
    if mat.shape[0] < mat.shape[1]:
        mat = mat.T
    first = [str(x) for x in mat[0]]
    cols = columns if columns is not None else _default_columns(path, first)
    if len(cols) != mat.shape[1]:
        raise DataError(f"{path!r}: the matrix has {mat.shape[1]} columns, columns= "
                        f"names {len(cols)}")
    values = {}
    for j, c in enumerate(cols):
        if c.role != "skip":
            col = mat[:, j]
            values[c.role] = col if c.role == "complex" else np.real(col)
    return cols, values, mat.shape[0]


# --------------------------------------------------------------------------- writer

def save_csv(data, path):
    """Write data as ``omega,real,imag`` CSV (atomic: temporary file then rename).

    Parameters
    ----------
    data : FrequencyData
    path : str or path-like
        ``omega`` in rad/s (the header ``omega [rad/sample]`` for normalised data, which
        :func:`load` reads back as such), values with ``repr`` precision (a round trip is
        bit-exact).
    """
    from .._textio import atomic_write_text

    unit = data.unit
    lines = ["omega,real,imag" if unit == "rad/s" else f"omega [{unit}],real,imag"]
    lines += [f"{w!r},{z.real!r},{z.imag!r}" for w, z in zip(data.omega.tolist(),
                                                            data.response.tolist())]
    atomic_write_text(path, "\n".join(lines) + "\n")


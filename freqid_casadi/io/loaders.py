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
import zipfile

import numpy as np

from ._mat import read_mat_arrays
from ._named import SAVEZ, band_unit, named_response, named_responses
from ._octave import is_octave_binary, is_octave_text
from ._touchstone import is_touchstone, load_touchstone
from ._traces import read_traces
from ._uff import load_uff, read_uff
from ._readfile import (MAX_ELEMENTS, MAX_FILE_BYTES, MAX_ROWS, DataWarning, _finish,
                        parse_band, read_regular_file)
from ._columns import ChannelChoice
from ._table import parse_columns, parse_freq_unit, read_table, table_response
from ..core.data import FrequencyData
from ..errors import DataError, OptionError

__all__ = ["load", "load_all", "is_uff", "is_mat", "read_npz_arrays", "load_text",
           "load_csv", "load_npz", "load_mat", "load_uff", "load_touchstone", "is_touchstone",
           "parse_band", "save_csv", "read_regular_file", "DataWarning", "MAX_FILE_BYTES",
           "MAX_ROWS", "MAX_ELEMENTS"]


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
        runs: which run; for a table of several sweeps one after another (an impedance
        analyser's repeated cycles, the frequency starting again): which sweep
        (:func:`load_text`).
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
        return load_npz(path, name, freq_unit=freq_unit, band=band, columns=cols,
                        parameter=parameter)
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
        outputs x inputs, ``frf(:,2,1)``) and each complex vector (``H21``, ``H22``); an
        ``.npz`` archive as a ``.mat`` file; a text table whose header gives several
        complete responses each of them (an oscilloscope's Bode export of CH1 and CH2, a
        network analyser's S-parameter columns, LTspice's traces), named as the header
        names it (``CH2``, ``S21``). Any other file gives the one response :func:`load`
        reads (a Touchstone file's chosen parameter: ``load(path, parameter="S21")``).
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
    if lower.endswith(".npz"):
        refuse_options(path, columns=parse_columns(columns))   # (this package's format)
        return _npz_all(path, freq_unit, columns, band)
    plain = lower.endswith(".json") or is_touchstone(lower)
    if not plain and is_uff(path):
        if parse_columns(columns) is not None:
            raise OptionError(f"{os.fspath(path)!r} is a universal file (UFF): its records "
                              "name their own units and values; drop columns= (--columns)")
        return list(load_uff(path, freq_unit=freq_unit, band=band))
    try:
        return [load(path, freq_unit=freq_unit, columns=columns, band=band)]
    except ChannelChoice as exc:
        if columns is not None or not exc.choices:
            raise
        return [load(path, name, freq_unit=freq_unit, band=band, **kw)
                for name, kw in exc.choices]


def is_mat(path):
    """Whether ``path`` is read as a MATLAB file: a ``.mat`` name, or a regular file of
    another name that begins as GNU Octave's text format (``# Created by Octave``, or
    ``# name:`` and ``# type:`` lines), which Octave's ``save`` writes by default, or as
    Octave's binary format (refused, saying how to save it).

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
    head = _head(path, 1200)
    return head is not None and (is_octave_text(head) or is_octave_binary(head))


def _head(path, size):
    """The first ``size`` bytes of the regular file ``path``, or None (not a regular file,
    or unreadable: a FIFO or a device is not opened, it may block; the reader names the
    problem)."""
    try:
        if not os.path.isfile(path):
            return None
        with open(path, "rb") as fh:
            return fh.read(size)
    except (OSError, TypeError, ValueError):
        return None


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
    head = _head(path, 512)
    if head is None:
        return False
    lines = [line.strip() for line in head.decode("latin-1").splitlines() if line.strip()]
    return len(lines) >= 2 and lines[0] == "-1" and re.match(r"\d+b?(\s|$)", lines[1]) \
        is not None


def refuse_options(path, *, record=None, parameter=None, columns=None, flag=False):
    """Refuse an option given to :func:`load` for a kind of file it does not apply to
    (it would be ignored): ``record`` of a .npz, .mat or Touchstone file (it chooses a UFF
    record or an LTspice run), ``parameter`` and ``columns`` of a UFF file (its records
    name their own values).

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
    own = lower.endswith(".npz") and _own_npz(path)       # omega/freq_hz and response
    if parameter is not None and (lower.endswith(_UFF_EXT) or own):
        raise OptionError(f"{spell('parameter')} chooses a parameter of a Touchstone file "
                          "(.s1p, .s2p, ..., .sNp, .ts), of a text table whose header "
                          "names S-parameters or the response variable of a .mat or .npz "
                          f"file of several, not of {path!r}; drop it")
    if columns is not None and (lower.endswith(_UFF_EXT) or own):
        raise OptionError(f"{spell('columns')} names the columns of a text table or of a "
                          f".mat or .npz matrix; {path!r} names its own "
                          f"{'arrays' if own else 'records'}: drop it")


def _own_npz(source):
    """Whether ``source`` (a path or the file's bytes as a stream) is an ``.npz`` archive
    of this package's format (``omega`` or ``freq_hz`` beside ``response``); False for
    anything unreadable (the reader says)."""
    try:
        with zipfile.ZipFile(source) as zf:
            names = {n[:-4] if n.endswith(".npy") else n for n in zf.namelist()}
    except (OSError, zipfile.BadZipFile, zipfile.LargeZipFile, ValueError):
        return False
    return "response" in names and bool({"omega", "freq_hz"} & names)


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
        line before each): which run (0-based); required when there are several. For a
        table of several sweeps one after another (each strictly monotone, the frequency
        starting again by at least half a sweep's span): which sweep (0-based), required
        when there are several.

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
    _refuse_other_format(path, payload)
    columns, freq_unit = parse_columns(columns), parse_freq_unit(freq_unit)
    table = read_traces(path, payload, columns, freq_unit, parameter=parameter, record=record)
    if table is None:
        table = read_table(path, payload, columns, freq_unit, max_rows=MAX_ROWS,
                           parameter=parameter, record=record)
    omega, response = table_response(table)
    unit = "rad/sample" if table.unit("freq") == "rad/sample" else "rad/s"
    return _finish(path, omega, response, name, lines=table.lines, unit=unit, band=band,
                   **band_unit(table.unit("freq")))


#: Text formats of circuit simulators and network analysers that are no table, by the
#: first word of their first line that is not a comment, and how to convert them.
_CITI_MDIF = ("scikit-rf reads it: skrf.io.{}(path).networks is a list of skrf.Network, one "
              "per swept value, and fc.fit takes a one-port Network as it is (or write one "
              "as a Touchstone file: network.write_touchstone('data'))")
_OTHER_FORMATS = {
    b"CITIFILE": ("a CITIfile (Keysight's data format)", _CITI_MDIF.format("citi.Citi")),
    b"<QUCS": ("a Qucs dataset", "export the data from Qucs as a CSV table or a Touchstone "
               "file"),
    b"VAR": ("an MDIF file (Keysight ADS)", _CITI_MDIF.format("mdif.Mdif")),
    b"BEGIN": ("an MDIF file (Keysight ADS)", _CITI_MDIF.format("mdif.Mdif")),
}
#: An MDIF block's typed column header (``% freq(real) S[1,1](complex)``).
_MDIF_HEADER = re.compile(rb"^\s*%\s*\S+\((?:real|complex|int)\)", re.MULTILINE)


def _refuse_other_format(path, payload):
    """DataError for a text format the readers do not parse as a table (CITIfile, Qucs
    dataset, MDIF), naming it and the conversion to a Touchstone file, instead of a
    header error that asks for columns no columns= can give."""
    for line in payload[:65536].splitlines():
        word = line.strip().split(b" ", 1)[0].upper()
        if not word or word[:1] in b"#!%":
            continue
        what, how = next((v for k, v in _OTHER_FORMATS.items() if word.startswith(k)),
                         (None, None))
        if what is not None and ("MDIF" not in what or _MDIF_HEADER.search(payload[:65536])):
            raise DataError(f"{path!r} is {what}, not a table the readers parse; {how}")
        return


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
                                f"{n} elements of {dtype}); save the file again with {SAVEZ}")
            found[key] = (shape, dtype)
    return found


def read_npz_arrays(path, payload):
    """The numeric arrays of an ``.npz`` archive by name (headers checked before reading,
    as :func:`load_npz`; empty and non-numeric arrays left out), for the readers of time
    records.

    Parameters
    ----------
    path : str
        The file, for messages.
    payload : bytes
        Its content.

    Returns
    -------
    dict of str to ndarray

    Raises
    ------
    DataError
        Not an archive, arrays above :data:`MAX_ELEMENTS`, no numeric array.
    """
    try:
        return _npz_arrays(path, payload, _npz_headers(path, payload))
    except DataError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile) as exc:
        raise DataError(f"cannot read {path!r} as .npz ({exc}); save it with {SAVEZ}") \
            from None


def _npz_arrays(path, payload, headers):
    """The numeric arrays of an ``.npz`` archive, by name, squeezed (as a ``.mat`` file's
    variables are read); others (strings, objects, dates) left out."""
    out = {}
    with np.load(io.BytesIO(payload), allow_pickle=False) as npz:
        for key, (_, dtype) in headers.items():
            if dtype.kind in "iufc" and np.prod(headers[key][0], dtype=object) > 0:
                a = np.squeeze(npz[key])                 # (an empty array is no data)
                out[key] = a if a.dtype.kind in "fc" else a.astype(float)
    if not out:
        raise DataError(f"{path!r} holds no numeric arrays; save with {SAVEZ}")
    return out


def _check_dtype(path, key, dtype, complex_ok):
    unit = " (rad/s)" if key == "omega" else ""
    if dtype.kind == "c" and not complex_ok:
        raise DataError(f"{path!r}: array {key!r} has dtype {dtype}: {key} must be real{unit}; "
                        f"save it as floats with {SAVEZ}")
    if dtype.kind not in "iufc":
        what = "datetimes" if dtype.kind in "Mm" else f"dtype {dtype}"
        raise DataError(f"{path!r}: array {key!r} holds {what}: {key} must be an array of "
                        f"numbers{unit}; save plain floats with {SAVEZ}")


def load_npz(path, name=None, *, freq_unit=None, band=None, columns=None, parameter=None):
    """Read data from a NumPy ``.npz`` archive.

    Parameters
    ----------
    path : str or path-like
        Arrays ``omega`` (rad/s; or ``freq_hz`` in Hz), ``response`` (complex) and
        optionally ``weights``, as :func:`save_npz` writes them. An archive another program
        wrote (``freq`` beside ``H1``, ``H2``, ``coh``) is read by its arrays' names as a
        ``.mat`` file's variables are (:func:`load_mat`: the frequency vector by its name
        and ``freq_unit``, the one complex response or ``parameter``, an FRF matrix's
        channels as ``data(:,3)``).
    name : str, optional
    freq_unit : {"Hz", "rad/s"}, optional
        Unit of the array ``omega`` when it is not in rad/s ("Hz": multiplied by 2 pi).
    band : (float, float), optional
        Keep only the points with ``lo <= f <= hi`` (Hz for ``freq_hz`` or
        ``freq_unit="Hz"``, else rad/s).
    columns : str or sequence of str, optional
        Of an archive holding one N x k matrix: the names of its columns (as
        :func:`load_mat`).
    parameter : str, optional
        Of an archive of several responses: the array that holds the one to read
        (``"H1"``, ``"data(:,3)"``).

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
                        f"with {SAVEZ}")
    try:
        headers = _npz_headers(path, payload)
        keys = set(headers)
        freq_key = "omega" if "omega" in keys or "freq_hz" not in keys else "freq_hz"
        missing = {freq_key, "response"} - keys
        if missing or parameter is not None or columns is not None:   # another program's
            arrays = _npz_arrays(path, payload, headers)
            try:
                return named_response(path, arrays, parameter, parse_columns(columns),
                                      freq_unit, band, name)
            except DataError:
                if keys & {"omega", "freq_hz", "response"}:     # this format, incomplete
                    raise DataError(f"{path!r} lacks array(s) {sorted(missing)}; save with "
                                    f"{SAVEZ}") from None
                raise
        for key, complex_ok in ((freq_key, False), ("response", True), ("weights", False)):
            if key in headers:
                _check_dtype(path, key, headers[key][1], complex_ok)
        with np.load(io.BytesIO(payload), allow_pickle=False) as npz:
            omega, response = npz[freq_key], npz["response"]
            weights = npz["weights"] if "weights" in keys else None
    except DataError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile) as exc:
        raise DataError(f"cannot read {path!r} as .npz ({exc}); save it with {SAVEZ}") \
            from None
    if freq_key == "freq_hz" and freq_unit == "rad/s":
        raise DataError(f"{path!r}: array 'freq_hz' is in Hz, but freq_unit='rad/s'; drop "
                        "freq_unit or rename the array")
    hz = freq_key == "freq_hz" or freq_unit == "hz"
    if hz:
        omega = 2 * np.pi * np.asarray(omega, float)
    return _finish(path, omega, response, name, weights, band=band,
                   **band_unit("hz" if hz else "rad/s"))


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
    return named_response(path, arrays, parameter, columns, freq_unit, band, name)


def _npz_all(path, freq_unit, columns, band):
    """Every response of an ``.npz`` archive: its one, as :func:`load_npz` reads it, for
    the package's own format; else as a ``.mat`` file's (:func:`_mat_all`)."""
    where, payload = read_regular_file(path)
    if payload.startswith(b"\x93NUMPY") or _own_npz(io.BytesIO(payload)):
        return [load_npz(path, freq_unit=freq_unit, band=band, columns=columns)]
    return named_responses(where, read_npz_arrays(where, payload), freq_unit,
                           parse_columns(columns), band)


def _mat_all(path, freq_unit, columns, band):
    """Every response of a ``.mat`` file beside its frequency axis (:func:`load_all`):
    complex vectors and matrix channels, else real N x 2 matrices of real and imaginary
    parts; the file's one response, as :func:`load_mat` reads it, when it holds fewer
    than two."""
    columns = parse_columns(columns)
    where, payload = read_regular_file(path)
    arrays = read_mat_arrays(where, payload, MAX_ELEMENTS)
    return named_responses(where, arrays, freq_unit, columns, band)


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


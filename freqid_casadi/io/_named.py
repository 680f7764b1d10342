"""A response among a file's named arrays: the variables of a MATLAB or Octave file, the
arrays of an ``.npz`` archive another program wrote (layer L1).

:func:`named_response` reads the one response :func:`freqid_casadi.io.loaders.load_mat`
and ``load_npz`` return: the arrays matched by name with the vocabulary of the text
reader (``omega``, ``freq_hz``, ``response``, ``mag_db``, ...), a frequency vector named
outside it (``freqs``, ``Freq_domain``: :func:`frequency_axis`), an axis of start and step
scalars, the one FRF beside cross-spectra and coherence, the channel ``parameter`` names,
or a single N x k matrix read as a headerless table. :func:`named_responses` gives every
response of such a file (``load_all``). Messages name the variables found and the option
that chooses among them.
"""

import dataclasses
import warnings

import numpy as np

from ._columns import recognise, written_values
from ._mat import (axis_variables, chosen_response, matrix_channels, records_hint,
                   response_parts, spectrum_kind, start_step_axis)
from ._readfile import DataWarning, _finish
from ._table import (Column, Table, _check_finite, _default_columns, _layout_problem,
                     _resolve_units, table_response)
from ..errors import DataError

__all__ = ["named_response", "named_responses", "frequency_axis", "band_unit", "SAVEZ"]


def band_unit(unit):
    """``scale`` and ``file_unit`` keywords of ``_finish`` for a table's frequency unit."""
    return ({"scale": 2 * np.pi, "file_unit": "Hz"} if unit == "hz" else
            {"scale": 1.0, "file_unit": unit})


#: Most columns of a file's only matrix read as a table (beyond: no response).
MAX_TABLE_COLUMNS = 16

#: How to save an archive the package reads as it is.
SAVEZ = "np.savez(path, omega=omega, response=response)"


def named_response(path, arrays, parameter, columns, freq_unit, band, name):
    """The one response among a file's named ``arrays`` that ``load_mat`` and ``load_npz``
    read (``parameter`` chooses among the arrays and an FRF matrix's channels).

    Parameters
    ----------
    path : str
        The file, for messages.
    arrays : dict of str to ndarray
        Its numeric variables (:func:`~freqid_casadi.io._mat.read_mat_arrays`).
    parameter, columns, freq_unit, band, name
        As ``load_mat``'s (``columns`` and ``freq_unit`` already parsed).

    Returns
    -------
    FrequencyData
    """
    n, alias = frequency_axis(arrays)
    return _response(path, arrays, n, matrix_channels(arrays, n), alias, parameter, columns,
                     freq_unit, band, name)


def _response(path, arrays, n, channels, alias, parameter, columns, freq_unit, band, name):
    """:func:`named_response` with the axis's length ``n``, its name ``alias``
    (:func:`frequency_axis`) and the matrix ``channels`` (``matrix_channels``) given."""
    if parameter is None:
        parameter = _beside_spectra(path, arrays, n)
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
    return _finish(path, omega, response, name, band=band, **band_unit(table.unit("freq")))


def _complex_vectors(arrays, n):
    """The complex vectors of a ``.mat`` file as long as its frequency vector (``n``; any
    length when 0: it has none), in file order."""
    return [k for k, a in arrays.items() if np.iscomplexobj(a) and np.ndim(a) == 1
            and np.size(a) > 1 and (not n or np.size(a) == n)]


def _beside_spectra(path, arrays, n):
    """The one complex vector of a ``.mat`` file whose name does not say it is a spectrum
    (:func:`spectrum_kind`) when every other one is (an analyser's ``Hf_chan_2`` beside
    ``Hf_Cross_Spec_chan_2``), noted; else None (the file is read as it names itself)."""
    found = _complex_vectors(arrays, n)
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


def named_responses(where, arrays, freq_unit, columns, band):
    """Every response among a file's named ``arrays`` (:func:`_mat_all`)."""
    n, alias = frequency_axis(arrays)
    one = (where, arrays, n, matrix_channels(arrays, n), alias)   # as load_mat reads it
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
        return [_response(*one, None, columns, freq_unit, band, None)]
    return [_response(where, arrays, n, channels, alias, key, None, freq_unit, band, key)
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


def frequency_axis(arrays):
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
    (:func:`frequency_axis`)."""
    named = {}
    if columns is None:
        for key, arr in arrays.items():
            col = recognise(key.rsplit(".", 1)[-1])
            if key == alias:
                col = Column("freq", _alias_unit(key), key)
            if col is not None and col.role != "skip":
                named[key] = dataclasses.replace(col, label=key)   # (its minus, its scale)
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
    values = written_values(cols, values)       # "-Im(Z)", "Freq [MHz]"
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
        found = _complex_vectors(arrays, frequency_axis(arrays)[0])
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
            "matrix and pass columns=...; " + (
                f"in Python: {SAVEZ}" if str(path).lower().endswith(".npz") else
                "for one channel of an FRF matrix, in MATLAB: freq_hz = <frequencies>; "
                "response = <matrix>(:, k); save('frf_k.mat', 'freq_hz', 'response', "
                "'-v7')"))
    key, mat = next(iter(arrays.items()))
    mat = np.asarray(mat)
    if mat.shape[0] < mat.shape[1]:
        mat = mat.T
    if columns is None and mat.shape[1] > MAX_TABLE_COLUMNS:
        # Octave's example image 'penny' (128 x 128) was offered columns= of 125 skips
        raise DataError(f"{path!r}: its only array, {key} ({mat.shape[0]} x {mat.shape[1]}"
                        f"{', complex' if np.iscomplexobj(mat) else ''}), is no response: a "
                        "response is a complex vector beside its frequencies, or a table of "
                        "a frequency column and real/imaginary or magnitude/phase columns "
                        "(columns= names them)")
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

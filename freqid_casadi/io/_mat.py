"""The numeric variables of a MATLAB ``.mat`` file, structs flattened (layer L1).

:func:`read_mat_arrays` reads a MATLAB v4 to v7.2 file (``scipy.io.loadmat``), or GNU Octave's
text format (:mod:`freqid_casadi.io._octave`, whatever the extension), into a dict
of numeric arrays named by their MATLAB path: ``u``, ``meas.input``, ``run(2).y``,
``runs{3}`` (structs, struct arrays and cell arrays flattened; strings and other classes
left out).
:func:`records_hint` tells whether such a file holds time records rather than a frequency
response; :func:`start_step_axis` builds the frequency axis a file gives by its start and
step (``f_start`` and ``df``) beside the response. Used by
:func:`freqid_casadi.io.loaders.load_mat` and the time-record reader
:func:`freqid_casadi.experiment.load_records_mat`.
"""

import io
import re

import numpy as np

from ..errors import DataError
from ._octave import is_octave_binary, is_octave_text, read_octave_arrays

__all__ = ["read_mat_arrays", "records_hint", "spectrum_kind", "start_step_axis",
           "axis_variables", "chosen_response", "response_parts", "matrix_channels",
           "matrix_records", "record_axis", "MIN_RECORD"]

#: Shortest vector counted as a time record.
MIN_RECORD = 16


def _whos(path, payload, max_elements):
    """Check the top-level headers (sizes before reading); None if scipy cannot list them
    (some MATLAB-written classes), in which case the read itself decides."""
    import scipy.io

    try:
        info = scipy.io.whosmat(io.BytesIO(payload))
    except NotImplementedError:
        raise DataError(f"{path!r} is a MATLAB v7.3 (HDF5) file; save it with "
                        "save(..., '-v7') or export the arrays to CSV") from None
    except Exception:                    # scipy raises ValueError, TypeError, ... on garbage
        return None
    for var, shape, _ in info:
        n = int(np.prod([int(d) for d in shape], dtype=object)) if shape else 1
        if n > max_elements:
            raise DataError(f"{path!r}: variable {var!r} claims shape {shape} ({n} elements), "
                            f"above the limit of {max_elements}; the file is damaged or too "
                            "large (freqid_casadi.io.loaders.MAX_ELEMENTS)")
    return info


def _flatten(prefix, value, out):
    if hasattr(value, "_fieldnames"):           # scipy's mat_struct (struct_as_record=False)
        value = {name: getattr(value, name) for name in value._fieldnames}
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(f"{prefix}.{key}" if prefix else key, item, out)
    elif isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray)
                                              and value.dtype == object):
        items = list(value) if not isinstance(value, np.ndarray) else list(value.ravel())
        if items and all(isinstance(v, (int, float, complex, np.number))
                         and not isinstance(v, bool) for v in items):
            out[prefix] = np.array(value, complex if any(
                isinstance(v, (complex, np.complexfloating)) for v in items) else float)
            return
        struct = all(isinstance(v, dict) or hasattr(v, "_fieldnames") for v in items)
        for k, item in enumerate(items):
            _flatten(f"{prefix}({k + 1})" if struct else f"{prefix}{{{k + 1}}}", item, out)
    elif isinstance(value, (int, float, complex, np.number)) and not isinstance(value, bool):
        out[prefix] = np.asarray(value)
    elif isinstance(value, np.ndarray) and value.dtype.kind in "iufc" and value.size:
        out[prefix] = value


def read_mat_arrays(path, payload, max_elements):
    """Numeric arrays of a ``.mat`` file by MATLAB path (``x``, ``s.field``, ``s(2).f``).

    Parameters
    ----------
    path : str
        The file, for messages.
    payload : bytes
        Its content.
    max_elements : int
        Largest array accepted (top-level sizes are checked before reading).

    Returns
    -------
    dict of str to ndarray
        In file order; vectors squeezed to 1-D, scalars 0-D.

    Raises
    ------
    DataError
        v7.3 (HDF5), not a MATLAB file, an array above ``max_elements``, no numeric data.
    """
    if is_octave_binary(payload):
        raise DataError(f"{path!r} is in Octave's binary format; in Octave save it as text "
                        "(save -text f.mat ..., Octave's default) or as a MATLAB file (save "
                        "-mat7-binary f.mat ...)")
    if is_octave_text(payload):
        mat = read_octave_arrays(path, payload.removeprefix(b"\xef\xbb\xbf").decode(
            "latin-1"), max_elements)    # numbers and headers are ASCII; strings skipped
    else:
        mat = _loadmat(path, payload, max_elements)
    out = {}
    for key, value in mat.items():
        if not key.startswith("__"):
            _flatten(key, value, out)
    for key, arr in out.items():
        if arr.size > max_elements:
            raise DataError(f"{path!r}: variable {key!r} holds {arr.size} elements, above the "
                            f"limit of {max_elements} (freqid_casadi.io.loaders.MAX_ELEMENTS)")
    if not out:
        raise DataError(f"{path!r} holds no numeric variables; save omega and response "
                        "(or time records u and y) as numeric arrays")
    return out


def _loadmat(path, payload, max_elements):
    """``scipy.io.loadmat`` of a binary file, its errors as DataErrors."""
    import scipy.io

    _whos(path, payload, max_elements)
    mat = None
    for kw in (dict(simplify_cells=True), dict(squeeze_me=True, struct_as_record=False)):
        try:                             # the second reading where the first trips on a
            mat = scipy.io.loadmat(io.BytesIO(payload), **kw)    # class it cannot simplify
            break
        except NotImplementedError:
            raise DataError(f"{path!r} is a MATLAB v7.3 (HDF5) file; save it with "
                            "save(..., '-v7') or export the arrays to CSV") from None
        except Exception as exc:         # scipy raises many types on garbage
            error = exc
    if mat is None:
        raise DataError(f"cannot read {path!r} as a MATLAB .mat file ({error}); save the "
                        "arrays with save(..., '-v7') (in Octave: save -mat7-binary, or save "
                        "-text)")
    return mat


#: Most columns (or rows) of a real matrix counted as records, one each (``u(:,2)``).
RECORD_COLUMNS = 8


#: Words of a variable's name (split at ``_``, digits and case changes) that say it holds
#: a spectrum an analyser saves beside the FRF, not a response: complex cross-spectra and
#: coherence estimates (``Hf_Cross_Spec_chan_2``, ``Gxy``, ``coh``), by what they hold.
_SPECTRUM_WORDS = {
    "coherence": ("coh", "coher", "coherence", "cohere", "mscohere", "gamma2"),
    "cross-spectrum": ("csd", "cpsd", "crossspec", "crossspectrum", "gxy", "gyx", "sxy",
                       "syx", "pxy", "pyx", "gfx", "gxf", "sfx", "sxf"),
}
#: A cross-spectrum named in two words (``Hf_Cross_Spec_chan_2``, ``crossSpectrum``): "cross"
#: beside one of these (alone, "cross" is no spectrum: ``H_cross_axis``).
_CROSS_WITH = ("spec", "spectrum", "spectra", "power", "psd")


def spectrum_kind(name):
    """What a complex variable holds when its name says it is a spectrum, not a
    response: ``"coherence"`` or ``"cross-spectrum"``; else None (an auto-spectrum is
    real: no complex vector is one).

    Parameters
    ----------
    name : str
        A MATLAB name (``Hf_Cross_Spec_chan_2``, ``meas.Gxy``, ``H(:,2)``).

    Returns
    -------
    str or None
    """
    leaf = name.rsplit(".", 1)[-1].split("(", 1)[0]
    words = re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+", leaf)
    words = {w.lower() for w in words} | {leaf.lower()}
    for kind, names in _SPECTRUM_WORDS.items():
        if words & set(names):
            return kind
    if "cross" in words and words & set(_CROSS_WITH):
        return "cross-spectrum"
    return None


def record_axis(m, most):
    """0 when the rows of the matrix ``m`` are records (at most ``most`` rows of
    :data:`MIN_RECORD` or more samples), 1 when its columns are, None otherwise (not a
    matrix, or too many of either).

    Parameters
    ----------
    m : ndarray
    most : int

    Returns
    -------
    int or None
    """
    if m.ndim != 2:
        return None
    if m.shape[0] <= min(m.shape[1], most) and m.shape[1] >= MIN_RECORD:
        return 0
    if m.shape[1] <= min(m.shape[0], most) and m.shape[0] >= MIN_RECORD:
        return 1
    return None


def matrix_records(arrays, most):
    """The rows (or columns) of each real matrix of ``arrays`` whose rows (or columns) are
    records (:func:`record_axis`), as vectors named as MATLAB indexes them:
    ``Acceleration(2,:)``, ``inputvalues(:,1)``.

    Parameters
    ----------
    arrays : dict of str to ndarray
    most : int
        Most records a matrix holds.

    Returns
    -------
    dict of str to ndarray
    """
    out = {}
    for key, a in arrays.items():
        m = np.squeeze(a)
        axis = record_axis(m, most) if a.ndim >= 2 and a.dtype.kind in "iuf" else None
        if axis == 0:
            out.update({f"{key}({i + 1},:)": m[i] for i in range(m.shape[0])})
        elif axis == 1:
            out.update({f"{key}(:,{j + 1})": m[:, j] for j in range(m.shape[1])})
    return out


def records_hint(path, arrays):
    """A DataError message when ``arrays`` look like time records (two or more real
    vectors of one length >= :data:`MIN_RECORD`, the columns of a matrix of at most
    :data:`RECORD_COLUMNS` counted each; none of them complex), else None."""
    if any(np.iscomplexobj(a) for a in arrays.values()):
        return None
    vectors = {k: a for k, a in arrays.items()
               if a.ndim == 1 and a.size >= MIN_RECORD and a.dtype.kind in "iuf"}
    vectors.update(matrix_records(arrays, RECORD_COLUMNS))
    by_size = {}
    for key, a in vectors.items():
        by_size.setdefault(a.size, []).append(key)
    # (the columns of one matrix alone are a table, f, re, im as often as records)
    groups = [keys for keys in by_size.values()
              if len(keys) >= 2 and len({k.split("(", 1)[0] for k in keys}) >= 2]
    if not groups:
        return None
    keys = max(groups, key=len)
    shown = ", ".join(keys[:6]) + (", ..." if len(keys) > 6 else "")
    return (f"{path!r} holds time records ({shown}: {vectors[keys[0]].size} samples each), "
            "not a frequency response: estimate it with 'freqid frf FILE --u NAME --y NAME' "
            "(add --period N for a periodic excitation, --fs HZ if the file gives no fs), or "
            "freqid_casadi.experiment.load_records_mat(path).channels[NAME]")


# --------------------------------------------------------------------------- start and step

#: Names of the scalars that give a frequency axis by its start and step (``f_start`` and
#: ``df``; or its start and end, the count from the response's length), lower case, by
#: what they give and the family of the axis: ``f`` (its unit from ``freq_unit``, or a
#: suffix ``_hz``) or ``w`` (rad/s).
_AXIS_NAMES = {
    "start": {"f": ("f_start", "fstart", "f0", "freq_start", "freqstart", "start_freq",
                    "startfreq", "f_min", "fmin", "freq_min", "f_begin", "fbegin"),
              "w": ("w_start", "wstart", "w0", "omega_start", "omega0", "w_min", "wmin",
                    "omega_min")},
    "step": {"f": ("df", "d_f", "f_step", "fstep", "delta_f", "deltaf", "freq_step",
                   "freqstep", "step_freq", "dfreq", "delta_freq", "f_res", "fres",
                   "freq_res", "freq_resolution", "frequency_resolution", "f_inc", "finc",
                   "freq_inc"),
             "w": ("dw", "d_w", "domega", "d_omega", "delta_w", "delta_omega", "w_step",
                   "wstep", "omega_step")},
    "end": {"f": ("f_end", "fend", "f_stop", "fstop", "freq_end", "freq_stop", "stop_freq",
                  "end_freq", "f_max", "fmax", "freq_max"),
            "w": ("w_end", "wend", "w_stop", "w_max", "wmax", "omega_end", "omega_max")},
    "count": {"": ("nf", "n_f", "nfreq", "n_freq", "nfreqs", "num_freq", "n_points",
                   "npoints", "npts", "num_points", "n_lines", "nlines")}}
#: A given end must lie within one step of the axis's last point (files write it as the
#: last point, one step beyond, or the last bin's edge); the rounding allowed beyond, in
#: steps.
_END_TOL = 1e-6


def _axis_role(name):
    """``(what, family, unit)`` of a variable's leaf name in :data:`_AXIS_NAMES`
    (``"df_hz"``: ``("step", "f", "hz")``), or None."""
    leaf = name.rsplit(".", 1)[-1].strip().lower()
    unit = None
    for suffix, which in (("_hz", "hz"), ("_rad_s", "rad/s"), ("_rads", "rad/s")):
        if leaf.endswith(suffix) and len(leaf) > len(suffix):
            leaf, unit = leaf[:-len(suffix)], which
            break
    for what, families in _AXIS_NAMES.items():
        for family, names in families.items():
            if leaf in names:
                return what, family, unit
    return None


def axis_variables(arrays):
    """The names of the real scalars of ``arrays`` that give a part of a frequency axis
    (start, step, end or count: :func:`start_step_axis`), in file order.

    Parameters
    ----------
    arrays : dict of str to ndarray
        A file's numeric variables (:func:`read_mat_arrays`).

    Returns
    -------
    list of str
    """
    return [key for key, arr in arrays.items() if _axis_role(key) is not None
            and np.size(arr) == 1 and not np.iscomplexobj(arr)]


def chosen_response(path, arrays, parameter, is_freq):
    """The variables of a ``.mat`` file that holds several responses (``H21`` and ``H22``
    beside one frequency axis) with ``parameter``, the one chosen, as its response: a
    complex vector named ``response``, or a real N x 2 matrix's columns as ``re`` and
    ``im`` (with a DataWarning); the frequency variables kept, every other array left out.

    Parameters
    ----------
    path : str
        The file, for messages.
    arrays : dict of str to ndarray
        Its numeric variables (:func:`read_mat_arrays`).
    parameter : str
        The response's MATLAB name (``H21``, ``frf.H21``; a channel of a matrix,
        ``H(:,3)``, when ``arrays`` holds :func:`matrix_channels`).
    is_freq : callable
        ``name -> bool``: a variable name the reader takes for a frequency vector.

    Returns
    -------
    dict of str to ndarray

    Raises
    ------
    DataError
        No such variable, or one that is not a response.
    """
    if parameter not in arrays and "(" in parameter:
        parameter = "".join(parameter.split())          # MATLAB's H(:, 3) is H(:,3)
    if parameter not in arrays:
        base = parameter.split("(", 1)[0]
        chans = [k for k in arrays if k.startswith(base + "(")]
        if base in arrays and chans and "(" in parameter:
            shape = " x ".join(map(str, np.shape(arrays[base])))
            raise DataError(f"{path!r}: {parameter!r} is not a channel of {base} ({shape}): "
                            f"its channels are {chans[0]} ... {chans[-1]} ({len(chans)})")
        # the responses first (complex arrays, matrix channels), then the others
        shown = sorted((k for k in arrays if np.size(arrays[k]) > 1),
                       key=lambda k: not np.iscomplexobj(arrays[k]))
        more = f", ... ({len(shown)} in all)" if len(shown) > 12 else ""
        raise DataError(f"{path!r} has no variable {parameter!r}; its arrays: "
                        f"{', '.join(shown[:12])}{more}: pass one of them as parameter= "
                        "(command line --parameter)")
    axis = axis_variables(arrays)
    out = {k: a for k, a in arrays.items() if k != parameter and (
        k in axis or np.size(a) > 1 and not np.iscomplexobj(a) and is_freq(k))}
    parts = response_parts(path, parameter, arrays[parameter], stacklevel=5)
    if parts is None:
        a = np.asarray(arrays[parameter])
        raise DataError(f"{path!r}: {parameter} ({' x '.join(map(str, a.shape)) or 'scalar'}"
                        f"{', real' if not np.iscomplexobj(a) else ''}) is not a response: "
                        "choose a complex vector, or a real N x 2 matrix of real and "
                        "imaginary parts")
    out.update({"response" if k == "complex" else k: v for k, v in parts.items()})
    return out


def matrix_channels(arrays, n):
    """Each channel of every complex array of two or more dimensions with exactly one of
    length ``n`` (an FRF matrix beside ``n`` frequencies: ``H``, 512 x 9, or MATLAB's
    ``modalfrf`` output ``frf``, 512 x 3 x 2), named as MATLAB indexes it: ``H(:,3)``,
    ``frf(:,2,1)``, ``FRF(3,:)`` (1-based).

    Parameters
    ----------
    arrays : dict of str to ndarray
        A file's numeric variables (:func:`read_mat_arrays`; MATLAB's singleton dimensions
        are already squeezed, so an ``N x 3 x 1`` array is named ``(:,k)``).
    n : int
        The number of frequencies.

    Returns
    -------
    dict of str to ndarray
        Complex vectors of length ``n``, in file order, channels in MATLAB's column-major
        order (the first index fastest).
    """
    out = {}
    for key, arr in arrays.items():
        a = np.asarray(arr)
        if not np.iscomplexobj(a) or a.ndim < 2 or a.size == max(a.shape):
            continue
        axes = [i for i, d in enumerate(a.shape) if d == n]
        if len(axes) != 1:
            continue
        rest = [d for i, d in enumerate(a.shape) if i != axes[0]]
        for index in np.ndindex(*reversed(rest)):        # MATLAB order: first index fastest
            index = list(reversed(index))
            where = index[:axes[0]] + [slice(None)] + index[axes[0]:]
            shown = [str(i + 1) for i in index]
            shown.insert(axes[0], ":")
            out[f"{key}({','.join(shown)})"] = a[tuple(where)]
    return out


def response_parts(path, name, array, stacklevel=4):
    """``{"complex": vector}`` of a complex vector, ``{"re": ..., "im": ...}`` of the two
    columns of a real N x 2 (or 2 x N) matrix (with a DataWarning saying so), else None:
    the array of a ``.mat`` file the reader takes for a response whatever its name.

    Parameters
    ----------
    path : str
        The file, for the note.
    name : str
        The array's MATLAB name.
    array : ndarray
    stacklevel : int
        Of the DataWarning.

    Returns
    -------
    dict of str to ndarray, or None
    """
    import warnings

    from ._readfile import DataWarning

    a = np.asarray(array)
    if np.iscomplexobj(a) and a.size > 1 and a.size == max(a.shape):
        return {"complex": a.reshape(-1)}
    if a.ndim == 2 and 2 in a.shape and max(a.shape) > 2 and not np.iscomplexobj(a):
        mat = np.asarray(a, float)
        mat = mat if mat.shape[1] == 2 else mat.T
        warnings.warn(f"{path!r}: read the two columns of {name} ({mat.shape[0]} x 2) as the "
                      "real and imaginary parts of the response; if they are magnitude and "
                      "phase, save the response as one complex vector", DataWarning,
                      stacklevel=stacklevel)
        return {"re": mat[:, 0], "im": mat[:, 1]}
    return None


def _axis_parts(arrays):
    """``{what: [(name, value, family, unit), ...]}`` of the real scalars named as a part
    of a frequency axis."""
    parts = {}
    for key, arr in arrays.items():
        role = _axis_role(key)
        if role is None or np.size(arr) != 1 or np.iscomplexobj(arr):
            continue
        value = float(np.asarray(arr, float).reshape(-1)[0])
        parts.setdefault(role[0], []).append((key, value, role[1], role[2]))
    return parts


def _one(path, parts, what):
    """The one ``(name, value, family, unit)`` the file gives for ``what`` (start, step,
    end, count), or None; DataError for two that differ."""
    found = parts.get(what, [])
    if len({value for _, value, _, _ in found}) > 1:
        shown = ", ".join(f"{name} = {value:g}" for name, value, _, _ in found)
        raise DataError(f"{path!r}: the frequency axis has two {what}s ({shown}); keep one "
                        "of them in the file")
    return found[0] if found else None


def start_step_axis(path, arrays, n, freq_unit):
    """The frequency axis a ``.mat`` file gives by scalars beside its response: a start and
    a step (``f_start``/``df``, ``f0``/``df``, ``fstart``/``fstep``, ``freq_start``/
    ``delta_f``, ...), ``f[k] = start + k step`` for the response's ``n`` points, or a
    start and an end (``fstart``/``fend``: ``n`` points from one to the other).

    Parameters
    ----------
    path : str
        The file, for messages.
    arrays : dict of str to ndarray
        Its numeric variables (:func:`read_mat_arrays`).
    n : int
        The length of the response.
    freq_unit : {"hz", "rad/s"} or None
        The unit of names of the ``f`` family without a unit suffix (``f_start``, ``df``);
        names ``w0``, ``dw``, ... are rad/s, and ``f_start_hz``, ``df_hz`` Hz.

    Returns
    -------
    (ndarray, str, str) or None
        The frequencies (in the file's unit), that unit ("hz" or "rad/s") and a label
        naming the variables used (``"f_start + k*df"``); None when the file names no
        start and no step.

    Raises
    ------
    DataError
        A start without a step or end (or a step without a start), two values for one
        part, a step that is not positive, an end or a count the axis does not meet, parts
        of different units, or a unit that is unknown (``f``-family names without
        ``freq_unit``).
    """
    parts = _axis_parts(arrays)
    start, step, end = (_one(path, parts, what) for what in ("start", "step", "end"))
    count = _one(path, parts, "count")
    if start is None and step is None:
        return None
    given = [p for p in (start, step, end) if p is not None]
    shown = ", ".join(f"{name} = {value:g}" for name, value, _, _ in given)
    if start is None or (step is None and end is None):
        lack = "its start (f_start, f0, fstart, freq_start; 0 when the first point is " \
            "DC)" if start is None else "its step (df, fstep, delta_f) or its end (f_end, fend)"
        raise DataError(f"{path!r} gives part of a frequency axis ({shown}) but not {lack}: "
                        "save the missing scalar beside the response, or save the "
                        "frequencies themselves as freq_hz (Hz) or omega (rad/s)")
    unit = _axis_unit(path, given, shown, freq_unit)
    if count is not None and int(round(count[1])) != n:
        raise DataError(f"{path!r}: {count[0]} = {count[1]:g} points, but the response has "
                        f"{n}; save the response and its axis of one sweep together")
    if step is None:
        return np.linspace(start[1], end[1], n), unit, f"{start[0]} .. {end[0]}"
    if not step[1] > 0:
        raise DataError(f"{path!r}: the frequency step {step[0]} = {step[1]:g} must be "
                        "positive; check the variable")
    f = start[1] + step[1] * np.arange(n)
    if end is not None and not abs(f[-1] - end[1]) <= (1 + _END_TOL) * step[1]:
        raise DataError(f"{path!r}: {start[0]} + k*{step[0]} over the response's {n} points "
                        f"ends at {f[-1]:.10g}, more than one step from {end[0]} = "
                        f"{end[1]:.10g}: the response and the axis are not of one sweep (or "
                        "the step is rounded); save the frequencies themselves as freq_hz "
                        "(Hz) or omega (rad/s)")
    return f, unit, f"{start[0]} + k*{step[0]}"


def _axis_unit(path, given, shown, freq_unit):
    """The unit ("hz" or "rad/s") of the axis parts ``given``: a suffix (``_hz``), the
    family (``w``: rad/s) or ``freq_unit``; DataError when they disagree or none says."""
    known = {unit or ("rad/s" if family == "w" else None) for _, _, family, unit in given}
    known.discard(None)                      # (f_start beside df_hz: Hz, as df_hz says)
    if len(known) > 1:
        raise DataError(f"{path!r}: the frequency axis's parts ({shown}) are in different "
                        "units; name them alike (f_start_hz and df_hz, or w0 and dw in "
                        "rad/s)")
    unit = known.pop() if known else freq_unit
    if unit is None:
        raise DataError(f"{path!r}: the frequency unit of {shown} is unknown: pass "
                        "freq_unit='Hz' or freq_unit='rad/s' (command line --freq-unit "
                        "hz|rad/s), or name the variables with the unit (f_start_hz, df_hz)")
    if freq_unit is not None and freq_unit != unit:
        raise DataError(f"{path!r}: freq_unit={freq_unit!r} contradicts {shown} ({unit}); "
                        "drop freq_unit or rename the variables")
    return unit

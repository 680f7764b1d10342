"""The numeric variables of a MATLAB ``.mat`` file, structs flattened (layer L1).

:func:`read_mat_arrays` reads a MATLAB v4 to v7.2 file (``scipy.io.loadmat``) into a dict
of numeric arrays named by their MATLAB path: ``u``, ``meas.input``, ``run(2).y``,
``runs{3}`` (structs, struct arrays and cell arrays flattened; strings and other classes
left out).
:func:`records_hint` tells whether such a file holds time records rather than a frequency
response. Used by :func:`freqid_casadi.io.loaders.load_mat` and the time-record reader
:func:`freqid_casadi.experiment.load_records_mat`.
"""

import io

import numpy as np

from ..errors import DataError

__all__ = ["read_mat_arrays", "records_hint", "MIN_RECORD"]

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
                        "arrays with save(..., '-v7')")
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


def records_hint(path, arrays):
    """A DataError message when ``arrays`` look like time records (two or more real
    vectors of one length >= :data:`MIN_RECORD`, none of them complex), else None."""
    vectors = {k: a for k, a in arrays.items()
               if a.ndim == 1 and a.size >= MIN_RECORD and a.dtype.kind in "iuf"}
    by_size = {}
    for key, a in vectors.items():
        by_size.setdefault(a.size, []).append(key)
    groups = [keys for keys in by_size.values() if len(keys) >= 2]
    if not groups:
        return None
    keys = max(groups, key=len)
    shown = ", ".join(keys[:6]) + (", ..." if len(keys) > 6 else "")
    return (f"{path!r} holds time records ({shown}: {vectors[keys[0]].size} samples each), "
            "not a frequency response: estimate it with 'freqid frf FILE --u NAME --y NAME' "
            "(add --period N for a periodic excitation, --fs HZ if the file gives no fs), or "
            "freqid_casadi.experiment.load_records_mat(path, u=NAME, y=NAME)")

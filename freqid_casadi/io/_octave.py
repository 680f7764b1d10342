"""GNU Octave's text format, the one ``save`` writes by default (layer L1).

Octave saves ``save frf.mat f H`` as text unless told ``-mat7-binary``: a comment line
``# Created by Octave ...``, then per variable ``# name: H``, ``# type: complex matrix``,
its size (``# rows:``/``# columns:`` or ``# ndims:`` and the dimensions) and its values,
complex ones written ``(re,im)``. :func:`is_octave_text` recognises such a file whatever
its extension; :func:`read_octave_arrays` reads its numeric variables into the same dict
of arrays by MATLAB path that :func:`freqid_casadi.io._mat.read_mat_arrays` returns for a
binary file (``s.field``, ``s(2).f``, ``c{3}``; vectors squeezed, scalars 0-D; strings
left out), so every ``.mat`` reader takes both.

Read: scalars, matrices and N-d arrays (real, complex, bool, integer, single), ranges,
diagonal and sparse matrices (made dense), strings (skipped), cells, scalar structs and
struct arrays; class objects are parsed and left out. At a type it does not parse (a
function handle) the reader stops, keeps the variables before it and says so.
"""

import re
import warnings

import numpy as np

from ._readfile import DataWarning
from ..errors import DataError

__all__ = ["is_octave_text", "is_octave_binary", "read_octave_arrays"]

#: The types Octave's text format writes (a ``# type:`` line naming another is not it).
_TYPES = re.compile(r"(global )?((float )?(complex )?(scalar|matrix|diagonal matrix)|"
                    r"bool( matrix)?|sparse (complex |bool )?matrix|"
                    r"u?int(8|16|32|64) (scalar|matrix)|string|sq_string|(scalar )?struct|"
                    r"cell|(\w+_)?range|null_(matrix|string|sq_string)|function handle|"
                    r"inline function|object|"
                    r"permutation matrix|class)")
_HEADER = re.compile(r"#\s*(\w[\w ,]*?)\s*:\s*(.*?)\s*$")

#: A value as Octave writes it: a real, ``Inf``/``NaN``/``NA``, or ``(re,im)``.
_COMPLEX = re.compile(r"\(\s*([^,()\s]+)\s*,\s*([^,()\s]+)\s*\)")


def is_octave_binary(payload):
    """True if ``payload`` (bytes) is Octave's own binary format (``save -binary``, the
    ``octave-workspace`` a crash writes): it starts ``Octave-1-L`` or ``Octave-1-B``."""
    return payload[:10] in (b"Octave-1-L", b"Octave-1-B")


def is_octave_text(payload):
    """True if ``payload`` (bytes) starts as Octave's text format does: a ``# Created by
    Octave`` line, or (another program writing it) a first line ``# name: ...`` followed
    by ``# type: ...``."""
    head = payload[:1200].lstrip(b"\xef\xbb\xbf").lstrip()
    if head.startswith(b"# Created by Octave"):
        return True
    lines = [t.strip() for t in head.splitlines()[:12]]
    for k, line in enumerate(lines[:-1]):      # comment lines may come first
        if line.startswith(b"# name:"):
            kind = lines[k + 1].partition(b":")[2].strip().decode("latin-1")
            return lines[k + 1].startswith(b"# type:") and bool(_TYPES.fullmatch(kind))
        if not line.startswith((b"#", b"%")):
            return False
    return False


class _Lines:
    """The file's lines with a cursor; blank lines are skipped where a value is read."""

    def __init__(self, path, text, max_elements=None):
        self.path, self.lines, self.k = path, text.splitlines(), 0
        self.max_elements = max_elements

    def count(self, key):
        """The next ``# key: N`` line's non-negative integer N."""
        value = self.header(key)[1]
        if not re.fullmatch(r"\d+", value):
            self.k -= 1
            self.fail(f"'# {key}: {value[:20]}' is not a count")
        return int(value)

    def check_size(self, n, what="array"):
        """Refuse an ``n``-element ``what`` above the reader's limit before allocating."""
        if self.max_elements is not None and n > self.max_elements:
            self.k -= 1
            self.fail(f"a {what} of {n} elements, above the limit of {self.max_elements} "
                      "(freqid_casadi.io.loaders.MAX_ELEMENTS)")

    def fail(self, what):
        line = min(self.k, len(self.lines) - 1) + 1
        raise DataError(f"{self.path!r} (Octave text format), line {line}: {what}; "
                        "save the arrays again with save -text or save -mat7-binary")

    def _skippable(self, k):
        """Blank, or a comment that is no ``# key: value`` header (Octave's load skips
        such lines between its blocks; its ``# Created by Octave 9, Tue ... 10:30:00``
        line holds a colon but is no header)."""
        text = self.lines[k].strip()
        return not text or (text[0] in "#%" and (not _HEADER.match(text)
                                                 or text.startswith("# Created by")))

    def skip(self):
        """Move past blank and comment lines."""
        while self.k < len(self.lines) and self._skippable(self.k):
            self.k += 1

    def header(self, key=None):
        """The next ``# key: value`` line as (key, value); blank and comment lines
        before it skipped."""
        self.skip()
        if self.k >= len(self.lines):
            self.fail(f"the file ends where '# {key or 'name'}:' was expected")
        m = _HEADER.match(self.lines[self.k].strip())
        if not m or (key is not None and m.group(1) != key):
            self.fail(f"expected '# {key or 'key'}: ...', found "
                      f"{self.lines[self.k].strip()[:60]!r}")
        self.k += 1
        return m.group(1), m.group(2)

    def peek_key(self):
        """The key of the next ``# key: value`` line, or None (end, or not a header)."""
        k = self.k
        while k < len(self.lines) and self._skippable(k):
            k += 1
        if k >= len(self.lines):
            return None
        m = _HEADER.match(self.lines[k].strip())
        return m.group(1) if m else None

    def values(self, n, complex_=False):
        """The next ``n`` values, across lines, in the order written."""
        out = []
        while len(out) < n:
            if self.k >= len(self.lines):
                self.fail(f"the file ends after {len(out)} of {n} values")
            text = self.lines[self.k].strip()
            if text.startswith("#"):
                self.fail(f"{len(out)} of {n} values before the next header")
            if text:
                out += _cells(text, complex_, self)
            self.k += 1
        if len(out) != n:
            self.fail(f"{len(out)} values where {n} were expected")
        return np.array(out, complex if complex_ else float)

    def integers(self, n):
        vals = self.values(n)
        if not np.all(np.isfinite(vals)) or np.any(vals < 0) or np.any(vals % 1):
            self.fail("a size is not a non-negative integer")
        return [int(v) for v in vals]


def _number(text, lines):
    t = text.lower()
    if t in ("na", "nan", "+nan", "-nan"):
        return float("nan")
    try:
        return float(t)
    except ValueError:
        lines.fail(f"{text[:30]!r} is not a number")


def _cells(text, complex_, lines):
    if complex_:
        found = _COMPLEX.findall(text)
        if not found or _COMPLEX.sub("", text).strip():
            lines.fail(f"{text[:40]!r} is not a row of complex values '(re,im)'")
        return [complex(_number(a, lines), _number(b, lines)) for a, b in found]
    return [_number(c, lines) for c in text.split()]


def _size(lines):
    """``rows``/``columns`` or ``ndims`` and the dimensions; (shape, column-major)."""
    key = lines.peek_key()
    if key == "rows":
        return (lines.count("rows"), lines.count("columns")), False
    if key == "ndims":
        return tuple(lines.integers(lines.count("ndims"))), True
    lines.header()
    lines.fail(f"expected '# rows:' or '# ndims:', found '# {key}:'")


def _array(lines, complex_):
    shape, column_major = _size(lines)
    n = int(np.prod(shape, dtype=object))
    lines.check_size(n)
    flat = lines.values(n, complex_)
    if column_major:
        return flat.reshape(shape, order="F")
    return flat.reshape(shape)                      # rows as written


def _range(lines):
    lines.skip()                         # the comment '# base, limit, increment[, reverse]'
    if lines.k >= len(lines.lines):
        lines.fail("the file ends where a range's base, limit and increment were expected")
    text = lines.lines[lines.k]
    lines.k += 1
    vals = _cells(text, False, lines)
    if len(vals) not in (3, 4):
        lines.fail(f"{text.strip()[:40]!r} is not a range's base, limit and increment")
    base, limit, inc = vals[:3]
    if not np.isfinite([base, limit, inc]).all():
        return np.array([], float)
    if inc == 0:                         # Octave writes 'base, length, increment' for it
        n = int(limit) if limit >= 0 and limit == int(limit) else 0
        lines.check_size(n, "range")
        return np.full(n, base)
    n = max(int(np.floor((limit - base) / inc + 1e-10)) + 1, 0)
    lines.check_size(n, "range")
    return base + inc * np.arange(n)


def _sparse(lines, complex_):
    nnz = lines.count("nnz")
    shape = (lines.count("rows"), lines.count("columns"))
    lines.check_size(shape[0] * shape[1], "sparse matrix (made dense)")
    out = np.zeros(shape, complex if complex_ else float)
    for _ in range(nnz):
        text = lines.lines[lines.k].strip() if lines.k < len(lines.lines) else ""
        parts = text.split(None, 2)
        if len(parts) != 3 or not all(p.isdigit() and 0 < int(p) <= n
                                      for p, n in zip(parts, shape)):
            lines.fail(f"{text[:40]!r} is not 'row column value' of a {shape[0]} x "
                       f"{shape[1]} sparse matrix")
        out[int(parts[0]) - 1, int(parts[1]) - 1] = _cells(parts[2], complex_, lines)[0]
        lines.k += 1
    return out


def _string(lines):
    n = lines.count("elements")
    for _ in range(n):
        length = lines.count("length")
        used = -1
        while used < length and lines.k < len(lines.lines):   # the text may hold newlines
            used += len(lines.lines[lines.k]) + 1
            lines.k += 1
    return None


def _fields(lines, count):
    out = {}
    for _ in range(count):
        name = lines.header("name")[1]
        out[name] = _value(lines, name)
    return out


def _dims(lines):
    """A struct's ``# ndims:`` and dimensions (1 x 1 where an old Octave wrote none)."""
    if lines.peek_key() != "ndims":
        return (1, 1)
    return tuple(lines.integers(lines.count("ndims")))


def _struct_array(lines):
    shape = _dims(lines)
    n = int(np.prod(shape, dtype=object))
    lines.check_size(n, "struct array")
    fields = _fields(lines, lines.count("length"))      # each a cell of `shape`
    items = [{} for _ in range(n)]
    for name, cell in fields.items():
        for k in range(n):
            items[k][name] = cell[k] if isinstance(cell, list) and k < len(cell) else None
    return items[0] if n == 1 else items


def _cell(lines):
    shape, _ = _size(lines)
    n = int(np.prod(shape, dtype=object))
    lines.check_size(n, "cell array")
    items = []
    for _ in range(n):                              # column-major, as Octave writes them
        name = lines.header("name")[1]
        items.append(_value(lines, name))
    return items


#: Octave's integer and bool types: their scalar and matrix forms read as reals.
_INT = re.compile(r"u?int(8|16|32|64) (scalar|matrix)$")


def _value(lines, name):
    """The value of the variable or field whose ``# name:`` was just read."""
    kind = lines.header("type")[1].removeprefix("global ")
    kind = kind.removeprefix("float ")             # single precision: read as double
    if kind in ("scalar", "bool") or (_INT.match(kind) and kind.endswith("scalar")):
        return lines.values(1)[0]
    if kind == "complex scalar":
        return lines.values(1, True)[0]
    if kind in ("matrix", "bool matrix") or (_INT.match(kind) and kind.endswith("matrix")):
        return _array(lines, False)
    if kind == "complex matrix":
        return _array(lines, True)
    if kind in ("diagonal matrix", "complex diagonal matrix"):
        shape, _ = _size(lines)
        lines.check_size(shape[0] * shape[1], "diagonal matrix (made dense)")
        diag = lines.values(min(shape), kind.startswith("complex"))
        out = np.zeros(shape, diag.dtype)
        out[np.arange(diag.size), np.arange(diag.size)] = diag
        return out
    if kind in ("sparse matrix", "sparse complex matrix", "sparse bool matrix"):
        return _sparse(lines, kind == "sparse complex matrix")
    if kind == "range" or kind.endswith("_range"):
        return _range(lines)
    if kind in ("string", "sq_string"):
        return _string(lines)
    if kind == "scalar struct":
        _dims(lines)
        return _fields(lines, lines.count("length"))
    if kind == "struct":
        return _struct_array(lines)
    if kind == "cell":
        return _cell(lines)
    if kind in ("null_matrix", "null_string", "null_sq_string"):     # [], "", ''
        if lines.peek_key() == "elements":
            _string(lines)
        elif lines.peek_key() in ("rows", "ndims"):
            _size(lines)                        # 0 x 0: no values follow
        return None
    if kind in ("object", "class"):            # a class object (tf, ss): its fields, dropped
        while lines.peek_key() not in ("length", None):
            lines.header()                     # classname, parents
        _fields(lines, lines.count("length"))
        return None
    lines.k -= 1
    raise _Unread(name, kind, lines.k + 1)


class _Unread(Exception):
    """A variable of a type the reader does not parse (a function handle): where the
    variables it can read end."""

    def __init__(self, name, kind, line):
        super().__init__(name, kind, line)
        self.name, self.kind, self.line = name, kind, line


def _squeezed(value):
    """As scipy's loadmat with ``simplify_cells``: arrays squeezed, scalars 0-D, cells as
    lists, structs as dicts."""
    if isinstance(value, dict):
        return {k: _squeezed(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_squeezed(v) for v in value]
    if isinstance(value, np.ndarray):
        return np.squeeze(value) if value.size else value
    return None if value is None else np.asarray(value)


def read_octave_arrays(path, text, max_elements=None):
    """The variables of an Octave text file, by name, as ``scipy.io.loadmat`` would give
    them (``simplify_cells=True``): arrays squeezed, structs as dicts, cells as lists,
    strings and empty matrices left out.

    Parameters
    ----------
    path : str
        The file, for messages.
    text : str
        Its content.
    max_elements : int, optional
        Largest array built (checked before allocating; a range, sparse or diagonal
        matrix counts its dense size).

    Returns
    -------
    dict

    Raises
    ------
    DataError
        A malformed block or a type this reader does not read, naming the line.
    """
    lines = _Lines(path, text, max_elements)
    out = {}
    while lines.peek_key() is not None:
        name = lines.header("name")[1]
        try:
            value = _squeezed(_value(lines, name))
        except _Unread as stop:
            warnings.warn(f"{path!r} (Octave text format), line {stop.line}: variable "
                          f"{stop.name!r} is of type {stop.kind!r}, which this reader does "
                          f"not read: read the {len(out)} variable(s) before it, not those "
                          "after it", DataWarning, stacklevel=4)
            return out
        if value is not None:
            out[name] = value
    lines.skip()
    if lines.k < len(lines.lines):
        lines.fail(f"{lines.lines[lines.k].strip()[:60]!r} is not a '# name:' line of a "
                   "variable")
    return out

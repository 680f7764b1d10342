"""GNU Octave's text format: what ``save frf.mat f H`` writes by default in Octave (not a
MATLAB binary file). ``fc.load``, ``fc.load_all``, ``freqid modal`` and the time-record
reader take it whatever its extension, as they take a MATLAB file.

The files are written here as Octave's ``save_ascii`` methods write them (a ``# Created
by Octave`` line, ``# name:``/``# type:`` blocks, 2-D arrays row by row under ``# rows:``
and ``# columns:``, N-d arrays and integer arrays one value per line in column-major order
under ``# ndims:``, complex values as ``(re,im)``, 17 significant digits).
"""

import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import DataError
from freqid_casadi.experiment import load_records_mat
from freqid_casadi.io._octave import is_octave_text, read_octave_arrays

F = np.linspace(1.0, 10.0, 40)
H = 1.0 / (1.0 + 1j * F[:, None] / np.arange(1.0, 4.0))      # 3 channels


def _v(x):
    x = complex(x)
    g = lambda t: "Inf" if t == np.inf else "-Inf" if t == -np.inf else (  # noqa: E731
        "NaN" if np.isnan(t) else f"{t:.17g}")
    return f"({g(x.real)},{g(x.imag)})" if isinstance(x, complex) and x.imag else g(x.real)


def _block(name, value):
    """One variable as Octave's save writes it."""
    if isinstance(value, str):
        return (f"# name: {name}\n# type: string\n# elements: 1\n# length: {len(value)}\n"
                f"{value}\n\n\n")
    a = np.asarray(value)
    cplx = np.iscomplexobj(a)
    fmt = (lambda x: f"({complex(x).real:.17g},{complex(x).imag:.17g})") if cplx else _v
    kind = "complex " if cplx else ""
    if a.ndim == 0:
        return f"# name: {name}\n# type: {kind}scalar\n{fmt(a)}\n\n\n"
    if a.ndim == 1:
        a = a[None, :]                                   # Octave's vectors are 1 x N
    if a.ndim == 2:
        rows = "".join(" " + " ".join(fmt(x) for x in row) + "\n" for row in a)
        return (f"# name: {name}\n# type: {kind}matrix\n# rows: {a.shape[0]}\n"
                f"# columns: {a.shape[1]}\n{rows}\n\n")
    dims = " ".join(str(d) for d in a.shape)
    values = "".join(f" {fmt(x)}\n" for x in a.ravel(order="F"))
    return (f"# name: {name}\n# type: {kind}matrix\n# ndims: {a.ndim}\n {dims}\n{values}"
            "\n\n")


def _octave(path, **variables):
    text = "# Created by Octave 8.4.0, Mon Dec 07 22:50:00 2026 UTC <lab@bench>\n"
    text += "".join(_block(k, v) for k, v in variables.items())
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", ["frf.mat", "frf.txt", "frf"])
def test_a_response_saved_by_octave_is_read_whatever_the_extension(tmp_path, name):
    path = _octave(tmp_path / name, units="Hz", fs=1024.0, f=F, H=H[:, 1])
    assert is_octave_text(path.read_bytes()) and fc.io.loaders.is_mat(path)
    data = fc.load(path, freq_unit="Hz")
    np.testing.assert_array_equal(data.response, H[:, 1])       # 17 digits: exact
    np.testing.assert_allclose(data.omega, 2 * np.pi * F, rtol=1e-15)


def test_every_channel_of_an_octave_frf_matrix_is_read(tmp_path):
    path = _octave(tmp_path / "modal.mat", freq_hz=F, H=H)
    datas = fc.load_all(path)
    assert [d.name for d in datas] == ["H(:,1)", "H(:,2)", "H(:,3)"]
    np.testing.assert_array_equal(np.array([d.response for d in datas]).T, H)
    np.testing.assert_array_equal(fc.load(path, parameter="H(:,3)").response, H[:, 2])


def test_nd_arrays_structs_cells_and_other_types(tmp_path):
    cube = (np.arange(24.0) + 1j).reshape(2, 3, 4)
    text = ("# Created by Octave 9.2.0\n"
            + _block("cube", cube)
            + "# name: s\n# type: scalar struct\n# ndims: 2\n 1 1\n# length: 2\n"
            + _block("f", F[:3]) + _block("note", "a\nb")
            + "\n\n# name: k\n# type: int32 matrix\n# ndims: 2\n 1 3\n 4\n 5\n 6\n\n\n"
            + "# name: b\n# type: bool\n1\n\n\n"
            + "# name: r\n# type: range\n# base, limit, increment\n0 2 0.5\n\n\n"
            + "# name: c\n# type: cell\n# rows: 1\n# columns: 2\n"
            + _block("<cell-element>", 2.5) + _block("<cell-element>", [1.0, 2.0])
            + "\n# name: d\n# type: diagonal matrix\n# rows: 2\n# columns: 2\n3\n4\n\n\n"
            + "# name: sp\n# type: sparse matrix\n# nnz: 1\n# rows: 2\n# columns: 2\n"
            + "2 1 7\n\n\n"
            + "# name: st\n# type: struct\n# ndims: 2\n 1 2\n# length: 1\n"
            + "# name: y\n# type: cell\n# rows: 1\n# columns: 2\n"
            + _block("<cell-element>", 1.0) + _block("<cell-element>", 2.0) + "\n")
    got = read_octave_arrays("x", text)
    np.testing.assert_array_equal(got["cube"], cube)
    np.testing.assert_array_equal(got["s"]["f"], F[:3])
    assert "note" not in got["s"]                              # strings are not data
    np.testing.assert_array_equal(got["k"], [4, 5, 6])
    assert got["b"] == 1.0
    np.testing.assert_array_equal(got["r"], [0, 0.5, 1, 1.5, 2])
    assert got["c"][0] == 2.5 and list(got["c"][1]) == [1, 2]
    np.testing.assert_array_equal(got["d"], [[3, 0], [0, 4]])
    np.testing.assert_array_equal(got["sp"], [[0, 0], [7, 0]])
    assert [item["y"] for item in got["st"]] == [1.0, 2.0]
    # through the .mat path: flattened to MATLAB names, as a binary file's
    path = tmp_path / "all.mat"
    path.write_text(text)
    arrays = fc.io.read_mat_arrays(str(path), path.read_bytes(), 10 ** 6)
    assert {"cube", "s.f", "k", "b", "r", "c{1}", "c{2}", "d", "sp", "st(1).y",
            "st(2).y"} == set(arrays)


def test_time_records_saved_by_octave_feed_the_records_reader(tmp_path):
    t = np.arange(256) / 1000.0
    u, y = np.sin(2 * np.pi * 50 * t), 0.5 * np.sin(2 * np.pi * 50 * t - 0.3)
    path = _octave(tmp_path / "run.txt", fs=1000.0, u=u, y=y)
    rec = load_records_mat(str(path))
    assert rec.fs == 1000.0 and set(rec.channels) == {"u", "y"}
    np.testing.assert_array_equal(rec.channels["y"], y)


@pytest.mark.parametrize("body, match", [
    ("# name: H\n# type: complex matrix\n# rows: 3\n# columns: 1\n (1,2)\n (3,4)\n\n",
     r"line 8: the file ends after 2 of 3 values"),
    ("# name: H\n# type: matrix\n# rows: 2\n# columns: 1\n 1\n x\n",
     r"line 7: 'x' is not a number"),
    ("# name: H\n# type: matrix\n# rows: 1.5\n# columns: 1\n 1\n",
     r"line 4: '# rows: 1.5' is not a count"),
    ("# name: H\n# type: complex matrix\n# rows: 1\n# columns: 2\n 1 2\n",
     r"line 6: '1 2' is not a row of complex values"),
])
def test_a_damaged_octave_file_is_refused_naming_the_line(tmp_path, body, match):
    path = tmp_path / "bad.mat"
    path.write_text("# Created by Octave 8.4.0\n" + body)
    with pytest.raises(DataError, match=r"'.*bad\.mat' \(Octave text format\), " + match):
        fc.load(path, freq_unit="Hz")


def test_single_precision_zero_step_ranges_and_limits(tmp_path):
    # Octave writes singles as 'float matrix', a range of step 0 as base, length, 0
    text = ("# Created by Octave 8.4.0\n# name: s\n# type: float matrix\n# rows: 1\n"
            "# columns: 3\n 0.5 1.5 2.5\n\n\n# name: c\n# type: float complex scalar\n"
            "(1,-2)\n\n\n# name: z\n# type: range\n# base, length, increment\n5 4 0\n\n\n")
    got = read_octave_arrays("x", text)
    np.testing.assert_array_equal(got["s"], [0.5, 1.5, 2.5])
    assert got["c"] == 1 - 2j
    np.testing.assert_array_equal(got["z"], [5.0, 5.0, 5.0, 5.0])
    # a claimed size above the limit is refused before anything is allocated
    huge = ("# Created by Octave 8.4.0\n# name: sp\n# type: sparse matrix\n# nnz: 0\n"
            "# rows: 1000000\n# columns: 1000000\n\n")
    with pytest.raises(DataError, match=r"line 6: a sparse matrix \(made dense\) of "
                       r"1000000000000 elements, above the limit of 1000"):
        read_octave_arrays("x", huge, max_elements=1000)
    with pytest.raises(DataError, match="a range of 1000000000001 elements"):
        read_octave_arrays("x", "# name: r\n# type: range\n0 1e12 1\n", max_elements=1000)


def test_a_damaged_count_is_a_data_error_and_a_table_with_name_lines_is_a_table(tmp_path):
    path = tmp_path / "bad.mat"
    path.write_text("# Created by Octave 8.4.0\n# name: a\n# type: matrix\n# rows: x\n"
                    "# columns: 2\n1 2\n")
    with pytest.raises(DataError, match=r"line 4: '# rows: x' is not a count"):
        fc.load(path, freq_unit="Hz")
    # a CSV whose comment lines happen to read '# name:' and '# type:' is no Octave file
    csv = tmp_path / "meta.csv"
    csv.write_text("# name: sweep 1\n# type: gain/phase\nfreq_hz,mag_db,phase_deg\n"
                   "10,0,-5\n20,-1,-10\n40,-3,-20\n")
    assert not is_octave_text(csv.read_bytes())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert fc.load(csv).n_points == 3


def test_files_as_octave_projects_publish_them(tmp_path):
    # a measurement table with a comment line before its variable; a cache whose first
    # line is another program's comment; a tf object beside numbers; an empty string and
    # matrix; a function handle, after which nothing is read (as published files have them)
    text = ("# Created by Octave 3.2.4\n#F[MHz]\tF [Hz]\tG\n# name: A2\n# type: matrix\n"
            "# rows: 2\n# columns: 2\n 1 2\n 3 4\n\n\n"
            "# name: sys\n# type: object\n# classname: tf\n# length: 1\n"
            "# name: num\n# type: matrix\n# rows: 1\n# columns: 2\n 1 2\n\n\n"
            "# name: s\n# type: null_string\n# elements: 0\n\n\n"
            "# name: e\n# type: null_matrix\n# rows: 0\n# columns: 0\n\n\n"
            "# name: k\n# type: scalar\n7\n\n\n"
            "# name: f\n# type: function handle\n@(x) x .^ 2\n\n\n"
            "# name: after\n# type: scalar\n1\n")
    from freqid_casadi.io.loaders import DataWarning

    with pytest.warns(DataWarning, match=r"line \d+: variable 'f' is of type 'function "
                      r"handle', which this reader does not read: read the 2 variable\(s\) "
                      r"before it, not those after it"):
        got = read_octave_arrays("x", text)
    assert set(got) == {"A2", "k"} and got["k"] == 7.0
    np.testing.assert_array_equal(got["A2"], [[1, 2], [3, 4]])
    cache = b"# doc-cache created by Octave 11.2.0\n# name: cache\n# type: cell\n"
    assert is_octave_text(cache)
    # Octave's binary format: said so, with how to save it readably
    binary = tmp_path / "octave-workspace"
    binary.write_bytes(b"Octave-1-L\x00\x00\x00\x00\x01abc")
    with pytest.raises(DataError, match=r"is in Octave's binary format; in Octave save it as "
                       r"text \(save -text f\.mat \.\.\., Octave's default\)"):
        fc.load(binary)


def test_an_image_sized_matrix_is_named_not_offered_columns(tmp_path):
    # Octave's example 'penny.mat' (128 x 128): offered columns= with 125 skips
    path = tmp_path / "penny.mat"
    path.write_text("# Created by Octave 3.0\n" + _block("P", np.arange(400.0).reshape(20, 20)))
    with pytest.raises(DataError, match=r"its only array, P \(20 x 20\), is no response"):
        fc.load(path, freq_unit="Hz")
    # an .npz whose empty arrays are no data: named as what is left
    npz = tmp_path / "linlin.npz"
    np.savez(npz, Z=np.zeros(0), cnu=np.arange(8.0), data=np.zeros((0, 3)))
    with pytest.raises(DataError, match=r"\(found cnu \(8\)\)"):
        fc.load(npz, freq_unit="Hz")

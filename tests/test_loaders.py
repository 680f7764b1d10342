"""Tests of freqid_casadi.io.loaders: every format and unit round-trips to the same data, and
every bad file is a DataError naming the file, the line or column, and the fix."""

import io
import os
import re
import sys
import warnings
import zipfile

import numpy as np
import pytest
import scipy.io

import freqid_casadi as fc
from freqid_casadi.cli import app as cli
from freqid_casadi.io import loaders
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.io.loaders import DataWarning, load, load_mat, load_npz, load_text, load_uff
from freqid_casadi.io._columns import recognise
from conftest import first_order_response  # noqa: E402

OMEGA = np.array([0.5, 1.25, 3.0, 7.5, 20.0, 64.0])
RESP = first_order_response(OMEGA)
F_HZ = OMEGA / (2 * np.pi)
DB = 20 * np.log10(np.abs(RESP))
DEG = np.degrees(np.angle(RESP))


def _write(tmp_path, text, name="frf.csv", encoding="utf-8"):
    path = tmp_path / name
    path.write_bytes(text.encode(encoding) if isinstance(text, str) else text)
    return path


def _rows(*cols, sep=","):
    return "".join(sep.join(repr(float(c[i])) if not isinstance(c[i], str) else c[i]
                            for c in cols) + "\n" for i in range(len(cols[0])))


def _same(data, rtol=1e-13):
    np.testing.assert_allclose(data.omega, OMEGA, rtol=rtol)
    np.testing.assert_allclose(data.response, RESP, rtol=rtol)


# ------------------------------------------------------------------ text layouts and units

@pytest.mark.parametrize("header, cols, sep, kw", [
    ("omega,real,imag", (OMEGA, RESP.real, RESP.imag), ",", {}),
    ("omega,magnitude_db,phase_deg", (OMEGA, DB, DEG), ",", {}),
    ("f [Hz],re,im", (F_HZ, RESP.real, RESP.imag), ",", {}),
    ("freq_hz;mag_db;phase_deg", (F_HZ, DB, DEG), ";", {}),
    ("frequency (rad/s)\tmag\tphase_rad", (OMEGA, np.abs(RESP), np.angle(RESP)), "\t", {}),
    ("w mag [dB] phase [deg]", (OMEGA, DB, DEG), "  ", {}),
    ("Frequency (Hz), Magnitude (dB), Phase (degrees)", (F_HZ, DB, DEG), ", ", {}),
    ("f,re,im", (F_HZ, RESP.real, RESP.imag), ",", {"freq_unit": "Hz"}),
    ("freq,re,im", (OMEGA, RESP.real, RESP.imag), ",", {"freq_unit": "rad/s"}),
    (None, (F_HZ, RESP.real, RESP.imag), " ", {"freq_unit": "hz"}),
    (None, (OMEGA, RESP.real, RESP.imag), ",", {"freq_unit": "rad/s"}),
    (None, (F_HZ, DB, DEG), "\t", {"freq_unit": "Hz", "columns": "f,mag_db,phase_deg"}),
    ("a;b;c", (F_HZ, DB, DEG), ";", {"columns": ("freq_hz", "mag_db", "phase_deg")}),
], ids=["omega-ri", "omega-db-deg", "f-Hz-bracket", "semicolon-hz-db", "tab-rad-lin-rad",
        "space-w-db", "spreadsheet-words", "f-with-freq-unit", "freq-rad", "headerless-space-hz",
        "headerless-comma-rad", "headerless-columns", "columns-override-header"])
def test_text_layouts_and_units_give_the_same_data(tmp_path, header, cols, sep, kw):
    text = (header + "\n" if header else "") + _rows(*cols, sep=sep)
    _same(load(_write(tmp_path, text), **kw))


def test_hz_data_loaded_with_freq_unit_equals_the_rad_s_data(tmp_path):
    rad = load(_write(tmp_path, "omega,real,imag\n" + _rows(OMEGA, RESP.real, RESP.imag)))
    hz = load(_write(tmp_path, _rows(F_HZ, RESP.real, RESP.imag), "hz.txt"), freq_unit="Hz")
    np.testing.assert_allclose(hz.omega, rad.omega, rtol=1e-15)
    assert np.array_equal(hz.response, rad.response)


@pytest.mark.parametrize("fmt", ["{r!r}+{i!r}j", "({r!r}+{i!r}j)", "{r!r}+{i!r}i",
                                 "({r!r} + {i!r}j)"])
def test_complex_literals(tmp_path, fmt):
    lines = [f"{w!r},{fmt.format(r=z.real, i=z.imag)}".replace("+-", "-").replace("+ -", "- ")
             for w, z in zip(OMEGA.tolist(), RESP.tolist())]
    _same(load(_write(tmp_path, "omega,response\n" + "\n".join(lines))), rtol=1e-15)
    headerless = "\n".join(s.replace(",", "\t") for s in lines)
    _same(load(_write(tmp_path, headerless, "h.txt"), freq_unit="rad/s"), rtol=1e-15)


def test_bom_crlf_comments_quotes_and_skip_column(tmp_path):
    body = "".join(f'"{w!r}";{z.real!r};{z.imag!r};x\r\n'
                   for w, z in zip(OMEGA.tolist(), RESP.tolist()))
    text = "\ufeff% exported\r\n\"omega\";\"real\";\"imag\";\"note\"\r\n" + body
    path = _write(tmp_path, text)
    # a column of a name the reader does not know beside one complete response: read,
    # and the warning says what was read and what was left out
    with pytest.warns(DataWarning, match=r"read 'omega', 'real', 'imag'; left out columns "
                      r"of names the reader does not know: 'note'"):
        _same(load(path), rtol=0)
    _same(load(path, columns="omega;re;im;skip"), rtol=0)


def test_headerless_without_freq_unit_names_the_option(tmp_path):
    path = _write(tmp_path, _rows(F_HZ, RESP.real, RESP.imag, sep=" "), "plain.txt")
    with pytest.raises(DataError, match=r"plain\.txt'.*frequency unit is unknown \(it has no "
                       r"header line; its columns are read as frequency, real, imaginary "
                       r"unless .*\): pass freq_unit='Hz' or freq_unit='rad/s' \(command "
                       r"line --freq-unit hz\|rad/s\)"):
        load(path)


def test_freq_unit_that_contradicts_the_header(tmp_path):
    path = _write(tmp_path, "omega,re,im\n1,2,3\n")
    with pytest.raises(DataError, match=r"freq_unit='hz' contradicts column 'omega' \(rad/s\)"):
        load(path, freq_unit="Hz")


def test_zero_frequency_rows_are_dropped_with_a_note(tmp_path):
    text = "omega,real,imag\n0,5,0\n" + _rows(OMEGA, RESP.real, RESP.imag)
    with pytest.warns(DataWarning, match=r"dropped 1 row\(s\) at zero frequency \(line 2\)"):
        data = load(_write(tmp_path, text))
    _same(data, rtol=0)


# ------------------------------------------------------------------ .npz, .mat, UFF

def test_npz_freq_hz_and_freq_unit(tmp_path):
    np.savez(tmp_path / "a.npz", freq_hz=F_HZ, response=RESP)
    _same(load(tmp_path / "a.npz"))
    np.savez(tmp_path / "b.npz", omega=F_HZ, response=RESP)
    _same(load(tmp_path / "b.npz", freq_unit="Hz"))


def test_npz_datetime_omega_is_refused(tmp_path):
    np.savez(tmp_path / "d.npz", omega=np.arange(6).astype("datetime64[D]"), response=RESP)
    with pytest.raises(DataError, match=r"d\.npz': array 'omega' holds datetimes: omega must "
                       r"be an array of numbers \(rad/s\); save plain floats"):
        load(tmp_path / "d.npz")


def _npy_header_only(shape):
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False,
                                               "shape": shape})
    return buf.getvalue() + b"\0" * 64


def test_npz_header_claiming_1e11_elements_is_refused_before_allocating(tmp_path):
    path = tmp_path / "huge.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("omega.npy", _npy_header_only((100_000_000_000,)))
        zf.writestr("response.npy", _npy_header_only((3,)))
    with pytest.raises(DataError, match=r"array 'omega' claims shape \(100000000000,\) "
                       r"\(100000000000 elements\), above the limit"):
        load(path)


def test_npz_truncated_member(tmp_path):
    path = tmp_path / "short.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("omega.npy", _npy_header_only((1000,)))
        zf.writestr("response.npy", _npy_header_only((1000,)))
    with pytest.raises(DataError, match=r"array 'omega' is truncated"):
        load(path)


@pytest.mark.parametrize("arrays, kw", [
    ({"omega": OMEGA, "response": RESP}, {}),
    ({"freq_hz": F_HZ, "H": RESP}, {}),
    ({"w": OMEGA.reshape(1, -1), "mag_db": DB, "phase_deg": DEG.reshape(-1, 1)}, {}),
    ({"f": F_HZ, "re": RESP.real, "im": RESP.imag}, {"freq_unit": "Hz"}),
    ({"frf": np.column_stack([F_HZ, DB, DEG])}, {"columns": "freq_hz,mag_db,phase_deg"}),
    ({"data": np.vstack([OMEGA, RESP.real, RESP.imag])}, {"freq_unit": "rad/s"}),
], ids=["omega-response", "freq_hz-H", "w-db-deg-shapes", "f-re-im", "matrix-columns",
        "matrix-transposed-default"])
def test_mat_round_trips(tmp_path, arrays, kw):
    scipy.io.savemat(tmp_path / "m.mat", arrays)
    _same(load(tmp_path / "m.mat", **kw))


def test_mat_errors(tmp_path):
    scipy.io.savemat(tmp_path / "m.mat", {"a": OMEGA, "b": RESP})
    with pytest.raises(DataError, match=r"m\.mat': cannot tell the variables apart \(found a "
                       r"\(6\), b \(6, complex\)\); name them omega"):
        load_mat(tmp_path / "m.mat")
    _write(tmp_path, b"MATLAB 5.0 garbage" * 10, "bad.mat")
    with pytest.raises(DataError, match=r"cannot read .*bad\.mat' as a MATLAB \.mat file"):
        load(tmp_path / "bad.mat")


def _uff_set(pyuff, x, z, node, label="Hz", ident="NONE", func_type=4, abscissa=18):
    return pyuff.prepare_58(
        binary=0, func_type=func_type, rsp_node=node, rsp_dir=1, ref_node=1, ref_dir=1,
        ord_data_type=6,
        abscissa_spacing=0, abscissa_spec_data_type=abscissa, abscissa_axis_units_lab=label,
        ordinate_spec_data_type=12, orddenom_spec_data_type=13, z_axis_spec_data_type=0,
        x=x, data=z, id1=ident)


# frequencies that UFF 58's abscissa format (%13.5e) stores exactly
F_UFF = np.array([0.5, 1.25, 3.0, 7.5, 20.0, 64.0])


def test_uff_written_by_pyuff_several_records(tmp_path):
    pyuff = pytest.importorskip("pyuff")
    path = tmp_path / "two.uff"
    pyuff.UFF(str(path)).write_sets([_uff_set(pyuff, F_UFF, RESP, 1, ident="point 1"),
                                     _uff_set(pyuff, F_UFF, 2 * RESP, 2)], mode="overwrite")
    both = load_uff(path)
    # several records: named by response and reference node and direction (+X: code 1)
    assert [d.name for d in both] == ["1+X/1+X", "2+X/1+X"]
    np.testing.assert_allclose(both[0].omega, 2 * np.pi * F_UFF, rtol=1e-15)
    np.testing.assert_allclose(both[0].response, RESP, rtol=1e-11)   # %20.11e ordinates
    np.testing.assert_allclose(both[1].response, 2 * RESP, rtol=1e-11)
    with pytest.raises(DataError, match=r"holds 2 frequency-response records: pass record=0\.\.1"):
        load(path)
    np.testing.assert_allclose(load(path, record=1).response, 2 * RESP, rtol=1e-11)
    with pytest.raises(DataError, match=r"record=2 is out of range"):
        load(path, record=2)


def test_an_exact_zero_in_one_uff_record_neither_refuses_the_others_nor_its_own(tmp_path):
    # a dam's modal test (26 records, quantised): exact zeros in 10 records refused every
    # record of the file, record=1 too; now record=K builds only record K, and a record's
    # zero points are dropped with a note (the relative error is not defined there)
    pyuff = pytest.importorskip("pyuff")
    path = tmp_path / "dam.unv"
    holed = RESP.copy()
    holed[[1, 4]] = 0.0
    pyuff.UFF(str(path)).write_sets([_uff_set(pyuff, F_UFF, holed, 1, ident="H 1"),
                                     _uff_set(pyuff, F_UFF, 2 * RESP, 2, ident="H 2")],
                                    mode="overwrite")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)                  # no note of record 0
        other = load(path, record=1)
    np.testing.assert_allclose(other.response, 2 * RESP, rtol=1e-11)
    with pytest.warns(DataWarning, match=r"record 0: dropped 2 point\(s\) whose response is "
                      r"exactly 0 \(at 1\.25, 20 Hz\)"):
        own = load(path, record=0)
    np.testing.assert_array_equal(own.omega, 2 * np.pi * F_UFF[[0, 2, 3, 5]])
    np.testing.assert_allclose(own.response, RESP[[0, 2, 3, 5]], rtol=1e-11)
    with pytest.warns(DataWarning, match="dropped 2 point"):
        assert [d.n_points for d in load_uff(path)] == [4, 6]


def test_uff_records_that_are_not_frequency_responses_are_named(tmp_path):
    # an analyser's export holds the FRF beside its coherence and a PSD (function types 4,
    # 6, 9): the FRF is read, the others skipped with a note naming them; a file of a PSD
    # or a time record alone is refused, saying what it holds
    pyuff = pytest.importorskip("pyuff")
    mixed = tmp_path / "mixed.uff"
    pyuff.UFF(str(mixed)).write_sets([
        _uff_set(pyuff, F_UFF, np.abs(RESP), 1, ident="coh", func_type=6),
        _uff_set(pyuff, F_UFF, RESP, 2, ident="H 2/1"),
        _uff_set(pyuff, F_UFF, np.abs(RESP) ** 2, 3, ident="psd", func_type=9)],
        mode="overwrite")
    with pytest.warns(DataWarning, match=r"skipped 2 of its 3 dataset-58 records, which are "
                      r"not frequency responses \(1 coherence, 1 power spectral density\); "
                      r"kept its 1 frequency-response record"):
        (frf,) = load_uff(mixed)
    assert frf.name == "H 2/1"
    np.testing.assert_allclose(frf.response, RESP, rtol=1e-11)
    with pytest.warns(DataWarning, match="skipped 2"):
        np.testing.assert_array_equal(load(mixed).response, frf.response)
    psd = tmp_path / "psd.uff"
    pyuff.UFF(str(psd)).write_sets([_uff_set(pyuff, F_UFF, np.abs(RESP) ** 2, 1,
                                             func_type=9)], mode="overwrite")
    with pytest.raises(DataError, match=r"psd\.uff' record 0: a power spectral density \(UFF "
                       r"function type 9\), not a frequency response; export the FRF"):
        load(psd)
    time_rec = tmp_path / "time.uff"
    pyuff.UFF(str(time_rec)).write_sets([
        _uff_set(pyuff, F_UFF, RESP.real, 1, func_type=1, abscissa=17),
        _uff_set(pyuff, F_UFF, RESP.real, 2, func_type=1, abscissa=17)], mode="overwrite")
    with pytest.raises(DataError, match=r"record 0: abscissa type 17 is not frequency \(18\)"
                       r".* \(and no other of its 2 records is a frequency response: 2 time "
                       r"record\)"):
        load_uff(time_rec)


UFF_58 = """    -1
    58
hand-written FRF
NONE
NONE
NONE
NONE
    4         1    1         0       NONE         1   3       NONE         1   3
         6         3         0  0.00000E+00  0.00000E+00  0.00000E+00
        18    0    0    0 Frequency            {unit:<20s}
        12    0    0    0 Acceleration         m/s^2
        13    0    0    0 Force                N
         0    0    0    0 NONE                 NONE
  1.00000E+00   2.00000000000E+00  -1.00000000000E+00
  2.00000E+00   1.00000000000E+00  -5.00000000000E-01
  4.00000E+00   2.50000000000E-01   5.00000000000E-01
    -1
"""


@pytest.mark.parametrize("unit, scale, kw", [("Hz", 2 * np.pi, {}), ("rad/s", 1.0, {}),
                                             ("", 1.0, {"freq_unit": "rad/s"})])
def test_uff_hand_written_ascii(tmp_path, unit, scale, kw):
    pytest.importorskip("pyuff")
    path = _write(tmp_path, UFF_58.format(unit=unit), "hand.unv")
    data = load(path, **kw)
    assert data.name == "hand-written FRF"
    np.testing.assert_allclose(data.omega, scale * np.array([1.0, 2.0, 4.0]), rtol=1e-15)
    np.testing.assert_array_equal(data.response, [2 - 1j, 1 - 0.5j, 0.25 + 0.5j])


def test_uff_without_pyuff_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyuff", None)
    path = _write(tmp_path, UFF_58.format(unit="Hz"), "x.uff")
    with pytest.raises(DataError, match=r"reading UFF files needs pyuff: pip install "
                       r"'freqid_casadi\[uff\]'"):
        load(path)


# ------------------------------------------------------------------ hostile files

def test_fifo_is_refused_without_blocking(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    os.mkfifo(tmp_path / "pipe.csv")
    with pytest.raises(DataError, match=r"pipe\.csv' is a FIFO \(named pipe\), not a regular "
                       r"file; save the data to a file"):
        load(tmp_path / "pipe.csv")


@pytest.mark.parametrize("reader", [load, load_npz, load_mat, load_uff, load_text])
def test_device_is_refused(reader):
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    with pytest.raises(DataError, match=r"'/dev/zero' is a character device, not a regular"):
        reader("/dev/zero")


def test_directory_and_missing(tmp_path):
    with pytest.raises(DataError, match="is a directory, not a data file; name the file"):
        load(tmp_path)
    with pytest.raises(DataError, match=r"data file not found: .*nope\.mat'; check the path"):
        load(tmp_path / "nope.mat")


def test_size_and_row_limits(tmp_path, monkeypatch):
    path = _write(tmp_path, "omega,real,imag\n" + _rows(OMEGA, RESP.real, RESP.imag))
    monkeypatch.setattr(loaders, "MAX_ROWS", 3)
    with pytest.raises(DataError, match=r"has more than 3 data rows \(limit "
                       r"freqid_casadi\.io\.loaders\.MAX_ROWS\); thin the data or raise"):
        load(path)
    from freqid_casadi.io import _readfile

    monkeypatch.setattr(_readfile, "MAX_FILE_BYTES", 50)   # the one every reader uses
    with pytest.raises(DataError, match=r"holds \d+ bytes, above the limit of 50 bytes"):
        load(path)


@pytest.mark.parametrize("text, match", [
    ("omega,real,imag\n1," + "7" * 200_000 + "x,1\n",
     r"line 2, column 'real': '7{37}\.\.\.' is not a number$"),
    ("omega,real,imag\n1,1_0,1\n",
     r"line 2, column 'real': '1_0' is not a number \(only ASCII decimal numbers"),
    ("omega,real,imag\n1,\u0661\u0662,1\n",
     r"line 2, column 'real': '\u0661\u0662' is not a number \(only ASCII decimal"),
    ("omega,response\n1,1+2k\n", r"line 2, column 'response': '1\+2k' is not a complex number"),
    ("omega,magnitude_db,phase_deg\n1,7000,0\n",
     r"line 2, column 'magnitude_db': 7000\.0 dB is outside the range of floating point "
     r"\(\|G\| = 10\^\(dB/20\) is infinite\); check that the column is in dB"),
    ("omega,magnitude_db,phase_deg\n1,-7000,0\n", r"-7000\.0 dB .* is zero\)"),
    ("omega,real,imag\n1,1e400,1\n", r"line 2, column 'real': inf is not finite: response "
                                     r"must be finite; remove or re-measure"),
    ("omega,real,imag\n-1,1,1\n", r"line 2, column 'omega': frequency -1\.0 is negative"),
    ("omega,real,imag\n1,1,1\n1,2,2\n", r"line 3, column .omega.: the frequencies must be "
                                        r"strictly increasing \(duplicated rows\)"),
    ("omega,mag,phase\n1,1,1\n", r"phase column 'phase' does not give its unit; name it "
                                 r"phase_deg or phase_rad"),
    ("1,2,3,4\n", r"has no header and 4 columns: cannot tell what they are; pass columns="),
    ("omega,real,imag\n1,2,3\n" + "1e308,1,1\n", None),
], ids=["200k-cell", "underscore", "arabic-digits", "bad-complex", "7000-dB", "minus-7000-dB",
        "overflow-literal", "negative-freq", "duplicate", "phase-no-unit", "4-cols", "ok-1e308"])
def test_bad_cells_are_data_errors_with_line_and_column_and_no_warning(tmp_path, text, match):
    path = _write(tmp_path, text)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if match is None:
            assert load(path).omega[-1] == 1e308
        else:
            with pytest.raises(DataError, match=match) as info:
                load(path)
            assert "frf.csv'" in str(info.value) and len(str(info.value)) < 600
    assert [str(w.message) for w in caught] == []


def test_non_utf8_and_binary(tmp_path):
    path = _write(tmp_path, b"omega,real,imag\n1,2,3\n2,\xff,3\n")
    with pytest.warns(DataWarning, match=r"is not UTF-8 \(byte 0xff on line 3\): read as "
                      r"Windows-1252"), pytest.raises(
            DataError, match=r"line 3, column 'real': '\xff' is not a number \(only ASCII"):
        load(path)
    with pytest.raises(DataError, match="holds NUL bytes"):
        load(_write(tmp_path, b"omega,real,imag\n1,2\x00,3\n"))


def test_bad_options_are_option_errors(tmp_path):
    path = _write(tmp_path, "omega,real,imag\n1,2,3\n")
    with pytest.raises(OptionError, match=r"freq_unit must be 'Hz' or 'rad/s', got 'kHz'"):
        load(path, freq_unit="kHz")
    with pytest.raises(OptionError, match=r"columns: unknown column name 'foo'; name each"):
        load(path, columns="f,foo,im")
    with pytest.raises(OptionError, match=r"columns='f,re': the columns must be one frequency"):
        load(path, columns="f,re")


# ------------------------------------------------------------------ command line

def test_cli_fit_reads_hz_text_with_freq_unit_and_columns(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    w = np.logspace(-1, 2, 20)
    g = first_order_response(w)
    rows = _rows(np.r_[0.0, w / (2 * np.pi)], np.r_[2.0, 20 * np.log10(np.abs(g))],
                 np.r_[0.0, np.degrees(np.angle(g))], sep="\t")
    _write(tmp_path, rows, "m.txt")
    code = cli.main(["fit", "m.txt", "--sections", "1", "--out", "rep"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "has no header and 3 columns" not in err          # 3 columns: f, re, im default
    assert "frequency unit is unknown" in err and "--freq-unit hz|rad/s" in err
    code = cli.main(["fit", "m.txt", "--sections", "1", "--out", "rep", "--freq-unit", "hz",
                     "--columns", "f,mag_db,phase_deg", "--quiet"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert err.startswith("note: 'm.txt': dropped 1 row(s) at zero frequency (line 1)")
    assert "Warning" not in err
    assert os.path.isfile("rep/model.json")
    model = fc.RationalDelayModel.load("rep/model.json")
    assert np.max(np.abs(model.frequency_response(w) / g - 1)) < 1e-6


def test_cli_columns_option_is_validated_by_argparse(capsys):
    code = cli.main(["fit", "x.csv", "--sections", "1", "--out", "r", "--columns", "f,bad"])
    err = capsys.readouterr().err
    assert code == 2 and "--columns" in err and "unknown column name 'bad'" in err


# ------------------------------------------------------------------ Touchstone

S1P = """! hand-written 1-port, MHz, dB/angle
# MHz S DB R 50
0 0 0
1.5 -6.020599913279624 90
3.0 20 -45
"""


def test_touchstone_s1p_hand_written(tmp_path):
    path = _write(tmp_path, S1P, "res.s1p")
    with pytest.warns(DataWarning, match=r"dropped 1 row\(s\) at zero frequency \(line 3\)"):
        data = load(path)
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([1.5e6, 3e6]), rtol=1e-15)
    np.testing.assert_allclose(data.response, [0.5j, 10 * np.exp(-0.25j * np.pi)], rtol=1e-12)
    with pytest.raises(OptionError, match="do not apply to Touchstone"):
        load(path, freq_unit="Hz")
    with pytest.raises(OptionError, match=r"parameter='S21' is not in this 1-port S-parameter "
                       r"file: it holds S11 only \(a reflection\); leave parameter out"):
        load(path, parameter="S21")


@pytest.mark.parametrize("fmt", ["ri", "ma", "db"])
def test_touchstone_s2p_written_by_scikit_rf(tmp_path, fmt):
    skrf = pytest.importorskip("skrf")
    f = np.array([1.0, 2.0, 5.0]) * 1e9
    s = np.zeros((3, 2, 2), complex)
    s[:, 0, 0], s[:, 1, 0] = 0.1 + 0.2j, RESP[:3]
    s[:, 0, 1], s[:, 1, 1] = 0.05j, -0.3 + 0.1j
    net = skrf.Network(frequency=skrf.Frequency.from_f(f, unit="Hz"), s=s, name="dut")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net.write_touchstone(str(tmp_path / "dut"), form=fmt)
    path = tmp_path / "dut.s2p"
    np.testing.assert_allclose(load(path, parameter="S21").response, RESP[:3], rtol=1e-6)
    np.testing.assert_allclose(load(path, parameter="s12").response, 0.05j, rtol=1e-6)
    with pytest.warns(DataWarning, match="read S11, the default, of a 2-port file"):
        default = load(path)
    np.testing.assert_allclose(default.response, 0.1 + 0.2j, rtol=1e-6)      # S11
    np.testing.assert_allclose(default.omega, 2 * np.pi * f, rtol=1e-9)


def test_touchstone_bad_rows(tmp_path):
    with pytest.raises(DataError, match=r"line 3: 3 numbers, but a 2-port record needs 9 "
                       r"\(1 frequency \+ 4 pairs\), and the file ends"):
        load(_write(tmp_path, "# Hz S RI R 50\n! c\n1 2 3\n", "x.s2p"))
    with pytest.raises(DataError, match=r"line 2: '1_0' is not a number"):
        load(_write(tmp_path, "# Hz S RI R 50\n1 1_0 3\n", "x.s1p"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(DataError, match=r"line 2: the frequency or S11 is outside the "
                           "floating-point range"):
            load(_write(tmp_path, "# Hz S DB R 50\n1 7000 90\n", "y.s1p"))


def test_cli_batch_passes_freq_unit_and_prints_notes(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    w = np.logspace(-1, 2, 20)
    g = first_order_response(w)
    _write(tmp_path / "in", _rows(np.r_[0.0, w / (2 * np.pi)], np.r_[2.0, g.real],
                                  np.r_[0.0, g.imag]), "hz.csv")
    code = cli.main(["batch", "in", "--out", "rep", "--sections", "1", "--freq-unit", "hz"])
    out, err = capsys.readouterr()
    assert code in (0, 1), out + err                  # 1: IPOPT's status, not the data
    assert err.startswith("note: ") and "hz.csv': dropped 1 row(s) at zero frequency" in err
    assert "Warning" not in err
    error = float(re.search(r"hz\.csv: .*max rel\. error ([-+.e0-9]+)", out).group(1))
    assert error < 1e-6                               # Hz read as Hz: the model fits


# ------------------------------------------------------------------ analysers' traces

_BODE100_SETUP = ("---Measurement Setup-------------------------------------------\r\n"
                  "Device Type: Bode100\r\nStart Frequency (Hz): 1\r\nStop Frequency (Hz): "
                  "64\r\nNumber of Points: 6\r\nSweep Mode: Logarithmic\r\nReference Signal: "
                  "CH1\r\n---------------------------------------------------------------\r\n")


def _bode100(tmp_path, header, columns, name="bode.csv"):
    """A file laid out as the Bode Analyzer Suite exports it (CRLF, a setup preamble,
    one column per trace and format), of the response RESP at F_UFF Hz."""
    rows = [",".join(repr(float(v)) for v in [f] + [col(g) for col in columns])
            for f, g in zip(F_UFF, RESP)]
    return _write(tmp_path, _BODE100_SETUP + header + "\r\n" + "\r\n".join(rows) + "\r\n",
                  name)


def test_bode100_export_with_two_traces_of_one_gain_is_read_as_written(tmp_path):
    # the gain in real/imag/dB (trace 1) and real/imag/degree (trace 2): real and imag of
    # trace 1 are read, the other four columns checked against them and named in a note
    path = _bode100(tmp_path, "Frequency (Hz),TR1: Gain (Real),TR1: Gain (Imag),TR1: Gain "
                    "(dB),TR2: Gain (Real),TR2: Gain (Imag),TR2: Gain (Degree)",
                    [np.real, np.imag, lambda g: 20 * np.log10(abs(g)), np.real, np.imag,
                     lambda g: np.degrees(np.angle(g))])
    with pytest.warns(DataWarning) as notes:
        data = load(path)
    np.testing.assert_array_equal(data.omega, 2 * np.pi * F_UFF)
    np.testing.assert_array_equal(data.response, RESP)
    said = " ".join(str(w.message) for w in notes)
    assert "skipped 8 line(s) of metadata before the header on line 9" in said
    assert ("read 'Frequency (Hz)', 'TR1: Gain (Real)', 'TR1: Gain (Imag)'; columns "
            "'TR1: Gain (dB)', 'TR2: Gain (Real)', 'TR2: Gain (Imag)', 'TR2: Gain (Degree)' "
            "give the same response in another form") in said


def test_bode100_impedance_with_its_series_inductance_reads_the_impedance(tmp_path):
    # as the Bode 100 exports an impedance shown as Ls (a 2016 export on a public
    # repository: 'TR2: Impedance (Ls)' is Im Z / omega to the last digit): the derived
    # quantity is not the response in another form; it is skipped, with a note
    ls = dict(zip(RESP, RESP.imag / (2 * np.pi * F_UFF)))
    path = _bode100(tmp_path, "Frequency (Hz),TR2: Impedance (Real),TR2: Impedance (Imag),"
                    "TR2: Impedance (Ls)", [np.real, np.imag, ls.get])
    with pytest.warns(DataWarning) as notes:
        data = load(path)
    np.testing.assert_array_equal(data.response, RESP)
    said = " ".join(str(w.message) for w in notes)
    assert ("skipped 'TR2: Impedance (Ls)': a quantity the analyser derives from the "
            "response") in said


@pytest.mark.parametrize("derived", ["Rs", "Ls", "Cs", "Rp", "Lp", "Cp", "Q", "D"])
def test_quantities_derived_from_an_impedance_are_skipped(derived):
    col = recognise(f"TR1: Impedance ({derived})")
    assert (col.role, col.unit) == ("skip", "derived")
    assert recognise(f"Gain ({derived})").role == "skip"
    assert recognise("Impedance (Ohm)").role == "complex"      # a physical unit stays one


def test_bode100_traces_of_different_quantities_are_refused_with_the_columns_to_pass(
        tmp_path):
    # a second trace that is not the response in another form (here 1e-3 |Z| in a
    # column named as the impedance's magnitude): the error says so and gives the
    # columns= that reads the impedance, which then works
    path = _bode100(tmp_path, "Frequency (Hz),TR2: Impedance (Real),TR2: Impedance (Imag),"
                    "TR2: Impedance (absolut)", [np.real, np.imag, lambda g: 1e-3 * abs(g)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        with pytest.raises(DataError, match=r"bode\.csv' line 10: column 'TR2: Impedance "
                           r"\(absolut\)' is not the response of columns 'TR2: Impedance "
                           r"\(Real\)', 'TR2: Impedance \(Imag\)' in another form .* e\.g\. "
                           r"columns='freq_hz,re,im,skip'"):
            load(path)
        data = load(path, columns="freq_hz,re,im,skip")
    np.testing.assert_array_equal(data.response, RESP)


@pytest.mark.parametrize("header, columns", [
    ("Frequency (Hz),TR1: Gain (dB),TR2: Gain (Degree)",
     [lambda g: 20 * np.log10(abs(g)), lambda g: np.degrees(np.angle(g))]),
    ("Frequency (Hz),TR1: Impedance (absolut),TR2: Impedance (Degree)",
     [abs, lambda g: np.degrees(np.angle(g))]),
    ("Frequency (Hz),Trace 1: Magnitude (dB),Trace 2: Phase (°)",
     [lambda g: 20 * np.log10(abs(g)), lambda g: np.degrees(np.angle(g))]),
])
def test_traces_in_magnitude_and_phase_are_one_response(tmp_path, header, columns):
    path = _bode100(tmp_path, header, columns)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        data = load(path)
    np.testing.assert_allclose(data.response, RESP, rtol=1e-13)


def test_two_complete_traces_of_different_quantities_stay_ambiguous(tmp_path):
    path = _bode100(tmp_path, "Frequency (Hz),TR1: Gain (Real),TR1: Gain (Imag),"
                    "TR2: Impedance (Real),TR2: Impedance (Imag)",
                    [np.real, np.imag, np.real, np.imag])
    with pytest.raises(DataError, match=r"two columns are 're'"):
        load(path)


def test_network_analyser_channels_get_the_columns_that_read_the_response(tmp_path):
    # the Digilent WaveForms network analyser's layout: '#' setup lines, the reference
    # channel's magnitude beside the measured channel's magnitude and phase. Which one is
    # the system's response is the user's to say: the error offers the one channel whose
    # columns make a response, and those columns read it
    text = ("#Digilent WaveForms Network Analyzer\r\n#Device Name: Discovery2\r\n"
            "Frequency (Hz),Channel 1 Magnitude (dB),Channel 2 Magnitude (dB),"
            "Channel 2 Phase (deg)\r\n" + "".join(
                f"{float(f)!r},0.0,{float(d)!r},{float(p)!r}\r\n"
                for f, d, p in zip(F_UFF, DB, DEG)))
    path = _write(tmp_path, text, "network.csv")
    with pytest.raises(DataError, match=r"two columns are 'mag'; to read channel 2, the one "
                       r"whose columns make a response, pass "
                       r"columns='freq_hz,skip,mag_db,phase_deg'"):
        load(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        data = load(path, columns="freq_hz,skip,mag_db,phase_deg")
    np.testing.assert_allclose(data.response, RESP, rtol=1e-12)
    np.testing.assert_array_equal(data.omega, 2 * np.pi * F_UFF)


def test_waveforms_phase_written_with_a_star_for_the_degree_sign(tmp_path):
    # WaveForms (Digilent) writes its phase column as "Channel 2 Phase (*)" on some
    # systems, the star standing for the degree sign; published exports of its network
    # analyser carry that header (with a '#' preamble and a blank line before it)
    text = ("#Digilent WaveForms Network Analyzer - Bode\n#Relative: yes\n\n"
            "Frequency (Hz),Channel 2 Magnitude (dB),Channel 2 Phase (*)\n" + "".join(
                f"{float(f)!r},{float(d)!r},{float(p)!r}\n"
                for f, d, p in zip(F_UFF, DB, DEG)))
    path = _write(tmp_path, text, "bode.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        data = load(path)
    np.testing.assert_allclose(data.response, RESP, rtol=1e-12)
    col = recognise("Channel 2 Phase (*)")
    assert (col.role, col.unit) == ("phase", "deg")


def test_a_universal_file_of_another_extension_is_read_as_one(tmp_path):
    # analysers name UFF exports by what they hold (a published binary 58b export is
    # UFF58B.FRF); the text reader refused its NUL bytes as "not a text CSV"
    pyuff = pytest.importorskip("pyuff")
    uff = tmp_path / "a.uff"
    pyuff.UFF(str(uff)).write_sets([_uff_set(pyuff, F_UFF, RESP, 1, ident="H 1")],
                                   mode="overwrite")
    frf = tmp_path / "EXPORT.FRF"
    frf.write_bytes(uff.read_bytes())
    data = load(frf)
    assert data.name == "H 1"
    np.testing.assert_allclose(data.response, RESP, rtol=1e-11)
    with pytest.raises(OptionError, match=r"is a universal file \(UFF\).*drop columns="):
        load(frf, columns="f,re,im")
    text = tmp_path / "table.frf"                   # a text table of that extension: a table
    text.write_text("omega,re,im\n1,1,0\n2,0.5,-0.5\n3,0.25,-0.5\n4,0.1,-0.3\n")
    assert load(text).n_points == 4


def test_a_universal_file_without_functions_says_what_it_holds(tmp_path):
    # a ground-vibration test's geometry and mode-shape exports (datasets 164, 15, 55)
    # were refused as "no dataset-58 records" alone
    pyuff = pytest.importorskip("pyuff")
    path = tmp_path / "geometry.unv"
    pyuff.UFF(str(path)).write_sets([
        pyuff.prepare_164(units_code=1, units_description="SI", temp_mode=1, length=1.0,
                          force=1.0, temp=1.0, temp_offset=273.15),
        pyuff.prepare_15(node_nums=[1, 2], def_cs=[0, 0], disp_cs=[0, 0], color=[1, 1],
                         x=[0.0, 1.0], y=[0.0, 0.0], z=[0.0, 0.0])], mode="overwrite")
    with pytest.raises(DataError, match=r"holds no dataset-58 \(function\) records: it holds "
                       r"1 x dataset 164 \(units\), 1 x dataset 15 \(nodes\); export the "
                       r"FRFs as UFF 58"):
        load(path)


@pytest.mark.parametrize("band, kept", [((11, 2000), [11, 1000, 2000]),
                                        ((10, 1000), [10, 11, 1000])])
def test_a_point_on_a_band_edge_is_kept(tmp_path, band, kept):
    # 11 Hz and 1000 Hz come back from rad/s as 10.999999999999998 and 999.9999999999999:
    # each edge was dropped
    path = tmp_path / "edge.csv"
    path.write_text("freq_hz,real,imag\n10,1,0\n11,1,0\n1000,1,0\n2000,1,0\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = fc.load(path, band=band)
    np.testing.assert_allclose(data.omega / (2 * np.pi), kept, rtol=1e-15)

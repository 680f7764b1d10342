"""A gallery of analyser and DAQ export layouts, read as written (issue 31, item 1).

Every file is written by the test in the layout its software documents or is known to
write (sources in docs/guide/reading-data.md): SignalCalc (Data Physics) single- and
multi-channel ASCII with a preamble, the ``Units:`` marker and a unit line ``Hz
(m/s²)(N)`` written in Windows-1252; a generic DAQ CSV with a metadata block; a European
semicolon export with decimal commas; LabVIEW measurement (.lvm) tags; magnitude/phase in
dB and degrees; Hz and rad/s; ``Frequency (Hz)`` headers; UTF-16 text; then ``band=``;
Touchstone of 1 to 5 ports, v1 and v2, against scikit-rf; MATLAB structs and time records.
"""

import argparse
import warnings

import numpy as np
import pytest
import scipy.io

import freqid_casadi as fc
from freqid_casadi.cli import common as cli_common
from freqid_casadi.cli import frf as cli_frf
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.experiment import frf_from_periodic, frf_from_records, load_records_mat
from freqid_casadi.io.loaders import DataWarning

F = np.array([0.0, 1.25, 2.5, 3.75, 5.0, 6.25])       # Hz, SignalCalc starts at 0 Hz
H = np.array([0.5 + 0.0j, 0.49 - 0.02j, 0.47 - 0.05j, -1.5 - 3.25j, 0.02 - 0.4j,
              -0.1 - 0.2j])


def _rows(sep, cols, end="\n"):
    return "".join(sep.join(repr(float(v)) for v in row) + end for row in zip(*cols))


def _load(path, **kw):
    """``fc.load`` and the DataWarning texts it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = fc.load(path, **kw)
    notes = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
    assert len(notes) == len(caught), [str(w.message) for w in caught]
    return data, notes


def _signalcalc(encoding="cp1252", sep="\t", marker=False, eol="\r\n", unit_sep=None):
    """A single-channel SignalCalc ASCII export (preamble, header, unit line, data)."""
    head = ["Data Physics SignalCalc Mobilyzer", "Title:\tFree-free beam, roving hammer",
            "Date:\t03/12/2019 14:02:11", "Units: Ratio", "Channel 1:\tAccel 3Z (m/s²)",
            "Channel 2:\tForce 1Z (N)", "Averages:\t5", "Window:\tForce/Exponential",
            "Resolution:\t1.25 Hz", ""]
    header = sep.join(("Frequency", "Real", "Imaginary"))
    units = ["Units:"] if marker else []
    unit_sep = sep if unit_sep is None else unit_sep
    rule = ["-" * 40] if marker else []          # a one-cell line before the data
    text = eol.join(head + [header] + units + [f"Hz{unit_sep}(m/s²)(N)"] + rule + [""])
    text += _rows(sep, (F, H.real, H.imag), eol)
    return text.encode(encoding)


@pytest.mark.parametrize("sep,unit_sep", [("\t", None), (",", None), (" ", None), (",", " ")])
@pytest.mark.parametrize("marker", [False, True])
def test_signalcalc_export_in_windows_1252_is_read_as_written(tmp_path, sep, unit_sep, marker):
    path = tmp_path / "H_3Z_1Z.txt"
    path.write_bytes(_signalcalc(sep=sep, marker=marker, unit_sep=unit_sep))
    data, notes = _load(path)
    np.testing.assert_array_equal(data.omega, 2 * np.pi * F[1:])      # Hz from the unit line
    np.testing.assert_array_equal(data.response, H[1:])
    assert any("is not UTF-8 (byte 0xb2 on line 5): read as Windows-1252" in n for n in notes)
    assert any("skipped 9 line(s) of metadata before the header on line 11" in n
               and "'Data Physics SignalCalc Mobilyzer'" in n for n in notes)
    assert any("read the units of line(s)" in n and "Frequency [hz], Real, Imaginary" in n
               for n in notes)
    assert any("dropped 1 row(s) at zero frequency" in n for n in notes)


def test_signalcalc_band_drops_points_outside_in_hz(tmp_path):
    path = tmp_path / "H.txt"
    path.write_bytes(_signalcalc())
    data, notes = _load(path, band=(2.0, 5.0))
    np.testing.assert_array_equal(data.omega, 2 * np.pi * F[2:5])
    np.testing.assert_array_equal(data.response, H[2:5])
    assert any("band [2, 5] Hz: kept 3 of 5 points (dropped 1 below 2 Hz, 1 above 5 Hz)" in n
               for n in notes)


def test_signalcalc_multichannel_names_its_header_and_reads_with_columns(tmp_path):
    text = ("Data written for H1,2 H1,3\n\tH1,2\t\tH1,3\t\nFrequency\tReal\tImag\tReal\tImag\n"
            "Units:\nHz\tm/s2/N\t\tm/s2/N\t\n" + _rows("\t", (F, H.real, H.imag, -H.real,
                                                            H.imag)))
    path = tmp_path / "multi.txt"
    path.write_text(text)
    with pytest.raises(DataError, match=r"unrecognised header 'Frequency,Real,Imag,Real,Imag' "
                       r"\(two columns are 're'\)"):
        fc.load(path)
    data, notes = _load(path, columns="f,skip,skip,re,im", freq_unit="Hz")
    np.testing.assert_array_equal(data.response, -H.real[1:] + 1j * H.imag[1:])
    assert any("skipped 5 line(s) of metadata before the data" in n for n in notes)


def test_daq_csv_with_metadata_block_and_magnitude_phase(tmp_path):
    mag_db, phase = 20 * np.log10(np.abs(H[1:])), np.degrees(np.angle(H[1:]))
    text = ("# Exported by DAQ suite 7.2\n# Test: shaker sine dwell\nDevice: cDAQ-9178\n"
            "Sample rate: 25600 Hz\nReference channel = ai0\n\n"
            "Frequency (Hz),Magnitude (dB),Phase (deg)\n" + _rows(",", (F[1:], mag_db, phase)))
    path = tmp_path / "daq.csv"
    path.write_text(text)
    data, notes = _load(path)
    np.testing.assert_allclose(data.response, H[1:], rtol=1e-13)
    np.testing.assert_array_equal(data.omega, 2 * np.pi * F[1:])
    assert any("skipped 3 line(s) of metadata" in n and "'Device: cDAQ-9178'" in n
               for n in notes)


def test_semicolon_decimal_comma_export_with_degree_sign(tmp_path):
    mag, phase = np.abs(H[1:]), np.degrees(np.angle(H[1:]))
    body = "".join(f"{f:.2f};{m:.6f};{p:.4f}\r\n".replace(".", ",")
                   for f, m, p in zip(F[1:], mag, phase))
    text = ("Messung: Balken 3\r\nDatum: 12.03.2019\r\n"
            "Frequency [Hz];Magnitude;Phase [°]\r\n" + body)
    path = tmp_path / "export.csv"
    path.write_bytes(text.encode("cp1252"))
    data, notes = _load(path)
    np.testing.assert_allclose(data.response, H[1:], rtol=2e-6, atol=2e-6)
    assert any("read as Windows-1252" in n for n in notes)


def test_rad_per_second_and_radians_band_in_rad_per_second(tmp_path):
    w = 2 * np.pi * F[1:]
    text = ("Model: plant 4\nomega (rad/s)\tamplitude\tphase (rad)\n" +
            _rows("\t", (w, np.abs(H[1:]), np.angle(H[1:]))))
    path = tmp_path / "w.txt"
    path.write_text(text)
    data, _ = _load(path)
    np.testing.assert_allclose(data.response, H[1:], rtol=1e-14)
    data, notes = _load(path, band=(10.0, 30.0))                   # rad/s, the file's unit
    np.testing.assert_array_equal(data.omega, w[(w >= 10) & (w <= 30)])
    assert any("band [10, 30] rad/s: kept 2 of 5" in n for n in notes)


def test_labview_lvm_tags_are_skipped_with_columns(tmp_path):
    lvm = ("LabVIEW Measurement\t\nWriter_Version\t2\nReader_Version\t2\nSeparator\tTab\n"
           "Decimal_Separator\t.\nMulti_Headings\tNo\nX_Columns\tOne\n***End_of_Header***\t\n"
           "\nChannels\t2\t\nSamples\t5\t5\nX_Dimension\tFrequency\tFrequency\n"
           "X0\t1.25\t1.25\nDelta_X\t1.25\t1.25\n***End_of_Header***\t\t\t\n"
           "X_Value\tH real\tH imag\tComment\n" + _rows("\t", (F[1:], H.real[1:],
                                                             H.imag[1:]), "\t\n"))
    path = tmp_path / "frf.lvm"
    path.write_text(lvm)
    with pytest.raises(DataError, match=r"unrecognised header .*pass columns="):
        fc.load(path)
    data, notes = _load(path, columns="f,re,im", freq_unit="Hz")
    np.testing.assert_array_equal(data.response, H[1:])
    # (15 lines before the header: the two ***End_of_Header*** lines are comment lines)
    assert any("skipped 13 line(s) of metadata before the data" in n for n in notes)


def test_key_value_preamble_before_headerless_data(tmp_path):
    path = tmp_path / "plain.txt"
    path.write_text("Title: beam\nPoints: 5\n" + _rows(" ", (F[1:], H.real[1:], H.imag[1:])))
    with pytest.warns(DataWarning), pytest.raises(DataError, match="frequency unit is unknown"):
        fc.load(path)
    data, notes = _load(path, freq_unit="Hz")
    np.testing.assert_array_equal(data.response, H[1:])
    assert any("skipped 2 line(s) of metadata before the data" in n for n in notes)


def test_encodings_utf16_declared_and_plain_utf8(tmp_path):
    text = "Frequency (Hz)\tReal (m/s²/N)\tImag (m/s²/N)\r\n" + _rows(
        "\t", (F[1:], H.real[1:], H.imag[1:]), "\r\n")
    path = tmp_path / "u16.txt"
    path.write_bytes(text.encode("utf-16"))                         # with its byte-order mark
    data, notes = _load(path)
    np.testing.assert_array_equal(data.response, H[1:])
    assert notes == []
    declared = ("# encoding: iso-8859-15\n# Operator: Jürgen (5 €)\n" + text).encode(
        "iso-8859-15")
    path = tmp_path / "latin9.txt"
    path.write_bytes(declared)
    data, notes = _load(path)
    np.testing.assert_array_equal(data.response, H[1:])
    assert notes and "read as iso8859-15 (as it declares)" in notes[0]
    path = tmp_path / "utf8.txt"
    path.write_bytes(text.encode("utf-8"))
    assert _load(path)[1] == []


def test_binary_is_still_refused_and_bad_band_is_an_option_error(tmp_path):
    path = tmp_path / "bin.csv"
    path.write_bytes(b"\xff\xfe\x00\x81binary")
    with pytest.raises(DataError, match=r"not a text CSV file \(not UTF-8\)"):
        fc.load(path)
    good = tmp_path / "g.csv"
    good.write_text("f_hz,re,im\n1,1,1\n2,1,1\n")
    for band in ((5, 1), (1,), "1:2", (0, float("inf")), (-1, 2)):
        with pytest.raises(OptionError, match="band"):
            fc.load(good, band=band)
    with pytest.raises(DataError, match=r"no data point in band \[5, 6\] Hz \(the data span "
                       r"1 to 2 Hz\)"):
        fc.load(good, band=(5, 6))


def _parser():
    p = argparse.ArgumentParser()
    return cli_common.add_data_options(p, records=True)


def test_cli_band_and_parameter_reach_the_reader(tmp_path, capsys):
    path = tmp_path / "H.txt"
    path.write_bytes(_signalcalc())
    args = _parser().parse_args(["--band", "2:5"])
    data = cli_common.load_data(args, str(path))
    assert data.n_points == 3
    err = capsys.readouterr().err
    assert "note: " in err and "kept 3 of 5 points" in err and "Warning" not in err
    for bad in ("5:2", "abc", "1", "1:inf"):
        with pytest.raises(SystemExit):
            _parser().parse_args(["--band", bad])
    with pytest.raises(OptionError, match="parameter='S21' chooses an S-parameter of a "
                                          "Touchstone file or of a table whose columns"):
        cli_common.load_data(_parser().parse_args(["--parameter", "S21"]), str(path))


# ----------------------------------------------------------------------------- Touchstone

skrf = pytest.importorskip("skrf")


def _network(ports, seed=0, unit="GHz"):
    rng = np.random.default_rng(seed)
    freq = skrf.Frequency(1, 3, 7, unit=unit)
    s = rng.normal(size=(7, ports, ports)) + 1j * rng.normal(size=(7, ports, ports))
    return skrf.Network(frequency=freq, s=s, z0=50)


@pytest.mark.parametrize("ports", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("form", ["ri", "ma", "db"])
def test_touchstone_v1_any_ports_equals_scikit_rf(tmp_path, ports, form):
    net = _network(ports)
    net.write_touchstone(str(tmp_path / "dut"), form=form)
    path = tmp_path / f"dut.s{ports}p"
    for i in range(ports):
        for j in range(ports):
            data, _ = _load(path, parameter=f"S{i + 1}{j + 1}")
            np.testing.assert_allclose(data.response, net.s[:, i, j], rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(data.omega, 2 * np.pi * net.f, rtol=1e-15)


def test_touchstone_4_port_s21_band_and_default_warning(tmp_path):
    net = _network(4)
    net.write_touchstone(str(tmp_path / "dut"), form="ri")
    path = tmp_path / "dut.s4p"
    data, notes = _load(path, parameter="S21", band=(1.5, 2.5))
    keep = (net.f >= 1.5e9) & (net.f <= 2.5e9)
    np.testing.assert_allclose(data.response, net.s[keep, 1, 0], rtol=1e-12)
    assert any("band [1.5, 2.5] GHz: kept 3 of 7" in n for n in notes)
    _, notes = _load(path)
    assert any("read S11, the default, of a 4-port file" in n for n in notes)
    with pytest.raises(OptionError, match=r"'S51' is not in this 4-port S-parameter file; "
                       r"choose one of S11 \.\.\. S44"):
        fc.load(path, parameter="S51")
    args = _parser().parse_args(["--parameter", "S21"])
    np.testing.assert_allclose(cli_common.load_data(args, str(path)).response,
                               net.s[:, 1, 0], rtol=1e-12)


_V2 = """! Touchstone 2.0, {n}-port, {fmt} matrix
[Version] 2.0
# MHz S RI R 50
[Number of Ports] {n}
{order}[Number of Frequencies] 2
[Reference] 50 50
{ref}
[Matrix Format] {fmt}
{info}[Network Data]
{data}[End]
"""


def _v2(n, fmt, order="", info=""):
    """A v2 file (values 0.1, 0.2, ... per stored entry) and its full matrices."""
    pairs = {"Full": [(i, j) for i in range(n) for j in range(n)],
             "Lower": [(i, j) for i in range(n) for j in range(i + 1)],
             "Upper": [(i, j) for i in range(n) for j in range(i, n)]}[fmt]
    if n == 2 and fmt == "Full" and order == "21_12":
        pairs = [(0, 0), (1, 0), (0, 1), (1, 1)]
    s = np.zeros((2, n, n), complex)
    lines = ""
    for k, f in enumerate((100.0, 250.0)):
        vals = [complex(0.1 * (m + 1) + k, -0.05 * (m + 1)) for m in range(len(pairs))]
        for (i, j), v in zip(pairs, vals):
            s[k, i, j] = v
            if fmt != "Full":
                s[k, j, i] = v                 # a triangle: the other half by symmetry
        cells = [f"{v.real!r} {v.imag!r}" for v in vals]
        lines += f"{f!r} " + "\n  ".join(cells) + "\n"
    text = _V2.format(n=n, fmt=fmt, order=f"[Two-Port Data Order] {order}\n" if order else "",
                      ref=" ".join(["50"] * (n - 2)), data=lines, info=info)
    return text, s


@pytest.mark.parametrize("n,fmt,order", [(2, "Full", "12_21"), (2, "Full", "21_12"),
                                         (3, "Lower", ""), (3, "Upper", ""), (4, "Full", "")])
def test_touchstone_v2_keywords_equal_scikit_rf(tmp_path, n, fmt, order):
    text, s = _v2(n, fmt, order)
    path = tmp_path / "dut.ts"
    path.write_text(text)
    net = skrf.Network(str(path))
    info = tmp_path / "info.ts"            # an information block (skrf does not read it)
    info.write_text(_v2(n, fmt, order, "[Begin Information]\n1 2 3\n[End Information]\n")[0])
    np.testing.assert_allclose(net.s, s, rtol=1e-15)       # the test's matrices are skrf's
    for i in range(n):
        for j in range(n):
            data, _ = _load(path, parameter=f"S{i + 1},{j + 1}")
            np.testing.assert_allclose(data.response, net.s[:, i, j], rtol=1e-15)
            data, _ = _load(info, parameter=f"S{i + 1}{j + 1}")
            np.testing.assert_allclose(data.response, net.s[:, i, j], rtol=1e-15)
            np.testing.assert_allclose(data.omega, 2 * np.pi * net.f, rtol=1e-15)


def test_touchstone_bad_files_name_the_fault(tmp_path):
    text, _ = _v2(3, "Lower")
    path = tmp_path / "bad.ts"
    path.write_text(text.replace("[Number of Frequencies] 2", "[Number of Frequencies] 3"))
    with pytest.raises(DataError, match=r"\[Number of Frequencies\] 3 but the network data "
                       "hold 2"):
        fc.load(path, parameter="S21")
    path.write_text(text.replace("[Number of Ports] 3\n", ""))
    with pytest.raises(DataError, match=r"number of ports is unknown"):
        fc.load(path, parameter="S21")
    p2 = tmp_path / "noise.s2p"
    p2.write_text("# GHz S RI R 50\n1 1 0 2 0 3 0 4 0\n2 1 1 2 1 3 1 4 1\n"
                  "! noise parameters\n1 1.5 0.5 30 0.2\n2 1.6 0.5 35 0.2\n")
    data, _ = _load(p2, parameter="S12")
    np.testing.assert_array_equal(data.response, [3, 3 + 1j])


# ----------------------------------------------------------------------------- MATLAB

def test_mat_struct_frf_fields_are_read(tmp_path):
    path = tmp_path / "frf.mat"
    scipy.io.savemat(path, {"frf": {"freq_hz": F[1:], "response": H[1:],
                                    "comment": "beam point 3"}})
    data, _ = _load(path, band=(2, 4))
    np.testing.assert_array_equal(data.response, H[2:4])


def _multisine(seed=3, noise=0.05, n=256, periods=6, lines=np.arange(3, 60, 3)):
    rng = np.random.default_rng(seed)
    spec = np.zeros(n // 2 + 1, complex)
    spec[lines] = np.exp(2j * np.pi * rng.random(lines.size))
    r1 = np.fft.irfft(spec, n)
    r1 /= r1.std()
    r = np.tile(r1, periods)
    y = 0.8 * np.roll(r, 2) + noise * rng.standard_normal(r.size)
    u = r + noise * rng.standard_normal(r.size)
    return u, y, r, lines


def test_mat_time_records_are_named_and_refused_as_an_frf(tmp_path):
    u, y, r, _ = _multisine()
    path = tmp_path / "rec.mat"
    scipy.io.savemat(path, {"test": {"force": u, "acc": y, "gen": r, "Fs": 2048.0,
                                     "operator": "A. N."}})
    with pytest.raises(DataError, match=r"holds time records \(test\.force, test\.acc, "
                       r"test\.gen: 1536 samples each\), not a frequency response: .*freqid "
                       r"frf FILE --u NAME --y NAME"):
        fc.load(path)
    rec = load_records_mat(path)
    assert rec.fs == 2048.0 and list(rec.channels) == ["test.force", "test.acc", "test.gen"]
    np.testing.assert_array_equal(rec.channels["test.acc"], y)


def test_noise_only_lines_are_not_excited_and_a_reference_decides(tmp_path):
    # a very noisy input: measured, the excited lines' power is 20-30 times the variance of
    # its mean over the periods, the noise lines' at most 7.1 (the rule: 10 times)
    u, y, r, lines = _multisine(noise=1.0, periods=8)
    est = frf_from_periodic(u, y, 256, periodic_rtol=5)
    np.testing.assert_array_equal(est.bins, lines)
    power = np.abs(np.fft.fft(u.reshape(8, 256), axis=1).mean(axis=0)[:129]) ** 2
    power[0] = 0
    loud = np.flatnonzero(power > 1e-2 * power.max())
    assert len(set(loud) - set(lines)) >= 30    # ... which the -20 dB rule alone would keep
    est = frf_from_periodic(u, y, 256, reference=r, periodic_rtol=5)
    np.testing.assert_array_equal(est.bins, lines)
    welch = frf_from_records(u, y, fs=1.0, nperseg=256, reference=r)
    np.testing.assert_array_equal(welch.bins, lines)             # not the leakage beside


def test_freqid_frf_reads_mat_records_by_name_with_reference_and_band(tmp_path, capsys):
    u, y, r, lines = _multisine()
    path = tmp_path / "rec.mat"
    scipy.io.savemat(path, {"test": {"force": u, "acc": y, "gen": r, "Fs": 2048.0}})
    out = tmp_path / "frf.csv"
    code = fc.cli.main(["frf", str(path), "--u", "test.force", "--y", "test.acc",
                        "--estimator", "h1", "--nperseg", "256", "--reference", "test.gen",
                        "--band", "50:300", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    data = fc.load(out)
    f = lines * 2048.0 / 256
    np.testing.assert_allclose(data.omega, 2 * np.pi * f[(f >= 50) & (f <= 300)], rtol=1e-12)
    np.testing.assert_allclose(data.response, 0.8 * np.exp(-2j * np.pi * lines[
        (f >= 50) & (f <= 300)] * 2 / 256), atol=0.05)     # measured 0.015 (Welch noise)
    assert "band 50:300 Hz: kept" in text
    code = fc.cli.main(["frf", str(path), "--period", "256", "--out", str(out), "--force"])
    err = capsys.readouterr().err
    assert code == 2 and "--u is required" in err and "test.force, test.acc, test.gen" in err
    assert "Traceback" not in err
    with pytest.raises(OptionError, match="--u names a variable of a .mat file"):
        csv = tmp_path / "uy.csv"
        csv.write_text("u,y\n" + _rows(",", (u, y)))
        cli_frf.read_excitation(argparse.Namespace(records=str(csv), u="x", y=None))


def test_header_with_its_unit_line_alone_needs_no_note(tmp_path):
    path = tmp_path / "short.csv"
    path.write_text("Frequency,Real,Imaginary\nHz (m/s²)(N)\n" + _rows(",", (F[1:], H.real[1:],
                                                                          H.imag[1:])))
    data, notes = _load(path)
    np.testing.assert_array_equal(data.omega, 2 * np.pi * F[1:])
    assert notes == []


def test_touchstone_mixed_mode_is_refused(tmp_path):
    text, _ = _v2(2, "Full", "12_21")
    path = tmp_path / "mm.ts"
    path.write_text(text.replace("[Network Data]", "[Mixed-Mode Order] D2,1 C2,1\n"
                                 "[Network Data]"))
    with pytest.raises(DataError, match=r"mixed-mode parameters .* are not read"):
        fc.load(path, parameter="S21")


def test_mat_struct_and_cell_arrays_are_flattened_by_path(tmp_path):
    from freqid_casadi.io import read_mat_arrays

    cells = np.empty(2, dtype=object)
    cells[0], cells[1] = np.arange(20.0), np.arange(30.0)
    path = tmp_path / "nested.mat"
    scipy.io.savemat(path, {"cel": cells, "S": np.array([{"a": np.ones(3)}, {"a": np.zeros(3)}],
                                                       dtype=object), "name": "text"})
    arrays = read_mat_arrays(str(path), path.read_bytes(), 10 ** 6)
    assert {k: v.shape for k, v in arrays.items()} == {
        "cel{1}": (20,), "cel{2}": (30,), "S(1).a": (3,), "S(2).a": (3,)}
    np.testing.assert_array_equal(arrays["cel{2}"], np.arange(30.0))


def test_tab_header_of_multiword_names_over_space_separated_data(tmp_path):
    path = tmp_path / "ws.txt"
    path.write_text("Title: roving hammer\nFrequency (Hz)\tReal Part\tImaginary Part\n" +
                    _rows("  ", (F[1:], H.real[1:], H.imag[1:])))
    data, notes = _load(path)
    np.testing.assert_array_equal(data.omega, 2 * np.pi * F[1:])
    np.testing.assert_array_equal(data.response, H[1:])
    assert len(notes) == 1 and "skipped 1 line(s) of metadata" in notes[0]


def test_mat_read_falls_back_when_scipy_cannot_simplify(tmp_path, monkeypatch):
    u, y, r, _ = _multisine()
    path = tmp_path / "rec.mat"
    scipy.io.savemat(path, {"test": {"force": u, "acc": y, "Fs": 2048.0}})
    real = scipy.io.loadmat

    def loadmat(*args, **kw):
        if kw.get("simplify_cells"):
            raise TypeError("'NoneType' object is not iterable")   # as on the issue's file
        return real(*args, **kw)

    monkeypatch.setattr(scipy.io, "loadmat", loadmat)
    rec = load_records_mat(path)
    assert rec.fs == 2048.0 and list(rec.channels) == ["test.force", "test.acc"]
    np.testing.assert_array_equal(rec.channels["test.force"], u)


def test_closing_lines_after_the_data_are_skipped_with_a_note(tmp_path):
    path = tmp_path / "foot.csv"
    path.write_text("Frequency (Hz),Real,Imag\n" + _rows(",", (F[1:], H.real[1:], H.imag[1:])) +
                    "[END]\nTotal points: 5\n")
    data, notes = _load(path)
    np.testing.assert_array_equal(data.response, H[1:])
    assert notes == ["'%s': skipped 2 line(s) after the data (lines 7-8, the first '[END]')"
                     % path]
    path.write_text("f_hz,re,im\n1,2,3\n2,3,4\ngarbage 5 6\n")         # not a closing line
    with pytest.raises(DataError, match="line 4"):
        fc.load(path)

"""Published analyser exports, each written by the test byte for byte in its instrument's
layout: a Siglent oscilloscope's Bode export of two complete channels, a VNA script's
``Freq,S11dB,S11deg,...`` sweeps in repeated blocks, German and Spanish headers, a
headerless four-column file, Digilent WaveForms' impedance export (``Trace th (*)``,
``Trace |Z| (Ohm)``) and the HP/Agilent 4294A's ASCII export of two trace blocks (|Z| and
theta, R and X, or a log magnitude and a phase: one response).
"""

import re
import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.io._columns import recognise, sparameter_of
from freqid_casadi.io.loaders import DataWarning


def _write(tmp_path, text, name, newline="\n"):
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode("utf-8"))
    return str(path)


def _load(path, **kw):
    """``fc.load`` and the DataWarning texts it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = fc.load(path, **kw)
    return data, [str(w.message) for w in caught if issubclass(w.category, DataWarning)]


def _polar(db, deg):
    return 10.0 ** (np.asarray(db) / 20.0) * np.exp(1j * np.deg2rad(deg))


# --------------------------------------------------------------------------- Siglent

_SIGLENT_PREAMBLE = """Instrument Name,SDS2104X HD
Serial Number,SDS2HBAX6R0124
Software Version,2.6.1.2.1.1
Awg Type,USB
DUT Input Source,CH4
DUT Output Source1,CH1
DUT Output Source2,CH2
DUT Output Source3,None
DUT Channel Gain,Auto
Sweep Type,Simple
Awg Amplitude,1V
Awg Offset,0V
Awg Amplitude reference level,1V
Awg Load,HighZ
Awg Amplitude Unit,Vpp
Sweep Mode,Logarithmic
Start Frequency,100Hz
Stop Frequency,1000000Hz
Sweep Line,400
Sweep Log(dec),20
Amplitude Mode,Vout/Vin
Amplitude Axis Type,Logarithmic
Amplitude Axis Range,-70.2dB,-22.2dB
Phase Unit,Degree
Phase Axis Range,-200Deg,0Deg
Bode Data
Number of Points,3
"""
_SIGLENT_ROWS = [(100.0, 0.0130968441, -1.19590744, -33.9263355, 88.2384129),
                 (112.201845, 0.00729680987, -1.35280926, -32.9614999, 88.0330135),
                 (125.892541, 0.00525304973, -1.49875138, -31.9484596, 87.9012471)]
_SIGLENT = (_SIGLENT_PREAMBLE
            + "Frequency(Hz),CH1 Amplitude(dB),CH1 Phase(Deg),CH2 Amplitude(dB),CH2 Phase(Deg)\n"
            + "100,0.0130968441,-1.19590744,-33.9263355,88.2384129\n"
            + "112.201845,0.00729680987,-1.35280926,-32.9614999,88.0330135\n"
            + "125.892541,0.00525304973,-1.49875138,-31.9484596,87.9012471\n")


def test_siglent_channels_are_recognised_each():
    # no space between the name and its unit: "CH1 Amplitude(dB)"
    assert [(c.role, c.unit) for c in map(recognise, (
        "Frequency(Hz)", "CH1 Amplitude(dB)", "CH1 Phase(Deg)", "CH2 Amplitude(dB)",
        "CH2 Phase(Deg)"))] == [("freq", "hz"), ("mag", "db"), ("phase", "deg"),
                                ("mag", "db"), ("phase", "deg")]


def test_siglent_bode_export_of_two_complete_channels_asks_which(tmp_path):
    path = _write(tmp_path, _SIGLENT, "siglent.csv")
    with pytest.raises(DataError) as err:
        _load(path)
    text = str(err.value)
    assert "it gives 2 channels, each a complete response" in text
    assert ("pass columns='freq_hz,mag_db,phase_deg,skip,skip' to read CH1 or "
            "columns='freq_hz,skip,skip,mag_db,phase_deg' to read CH2") in text
    # the header is on line 28, after the preamble: the message says so
    assert "the header (line 28) must be" in text and "the first line" not in text
    f, _, _, db2, deg2 = np.array(_SIGLENT_ROWS).T
    data, notes = _load(path, columns="freq_hz,skip,skip,mag_db,phase_deg")
    np.testing.assert_allclose(data.omega, 2 * np.pi * f, rtol=1e-15)
    np.testing.assert_allclose(data.omega[0], 628.3185307179587, rtol=1e-15)
    np.testing.assert_allclose(data.response, _polar(db2, deg2), rtol=1e-13)
    # -33.9263355 dB at 88.2384129 degrees, by hand
    np.testing.assert_allclose(data.response[0], 0.000618580592 + 0.020113049689j,
                               rtol=1e-9)
    assert any("skipped 28 line(s) of metadata before the data (lines 1-28, the first "
               "'Instrument Name,SDS2104X HD')" in n for n in notes)
    # load_all reads both, named as the header names them
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        both = fc.load_all(path)
    assert [d.name for d in both] == ["CH1", "CH2"]
    np.testing.assert_array_equal(both[1].response, data.response)
    f, db1, deg1 = np.array(_SIGLENT_ROWS).T[:3]
    np.testing.assert_allclose(both[0].response, _polar(db1, deg1), rtol=1e-13)


def test_a_header_on_the_first_line_is_still_named_so(tmp_path):
    path = _write(tmp_path, "Frequency(Hz),CH1 Amplitude(dB),CH1 Phase(Deg),"
                  "CH2 Amplitude(dB)\n100,0.01,-1.2,-33.9\n200,0.02,-2.4,-27.9\n",
                  "one.csv")
    with pytest.raises(DataError, match=r"to read channel 1, the one whose columns make a "
                       r"response, pass columns='freq_hz,mag_db,phase_deg,skip'.*the first "
                       r"line must be"):
        fc.load(path)


# --------------------------------------------------------------------------- VNA blocks

_VNA_HEAD = ("HEADER,Raster Number, RF Direction,Polarization,Date,Time,\n"
             ",0,Tx,Horizontal,2019/03/13,16:44:58\n"
             "BS1,BS2,RT1\n"
             "-10,-10,0.0\n"
             "AO settings - B2AO0,...,B2AO31,B1AO0,...,B1AO31 \n"
             + ",".join(f"{1 + 0.0625 * k:.4f}" for k in range(64)) + "\n"
             "Freq,S11dB,S11deg,S21dB,S21deg,S12dB,S12deg,S22dB,S22deg\n")
_VNA_ROWS = (
    "7.50000000000E+10,-1.52499778591E+01,+1.11351589345E+02,-3.02961164934E+01,"
    "-2.84538977571E+00,-2.99447763008E+01,+2.24895239920E+01,-1.50255023844E+01,"
    "+1.69584910460E+02\n"
    "7.50500000000E+10,-1.51846957146E+01,+1.08189914423E+02,-2.98210175981E+01,"
    "-1.37009881057E+01,-3.03336907299E+01,+1.25907460844E+01,-1.33885563445E+01,"
    "+1.50108475461E+02\n"
    "7.51000000000E+10,-1.51709291587E+01,+1.05072040976E+02,-2.93970011959E+01,"
    "-2.48244296044E+01,-2.96135264997E+01,+1.66405636505E+00,-1.22274772815E+01,"
    "+1.29159040396E+02\n")
_S21 = _polar([-30.2961164934, -29.8210175981, -29.3970011959],
              [-2.84538977571, -13.7009881057, -24.8244296044])


@pytest.mark.parametrize("name, role, unit", [
    ("S21dB", "mag", "db"), ("S21deg", "phase", "deg"), ("S21re", "re", None),
    ("S21im", "im", None), ("S21mag", "mag", "lin"), ("S21_dB", "mag", "db"),
    ("S21 deg", "phase", "deg"), ("S21_re", "re", None), ("S21 im", "im", None),
    ("S12rad", "phase", "rad")])
def test_an_sparameter_glued_to_its_format_is_that_parameter_s_column(name, role, unit):
    col = recognise(name)
    assert (col.role, col.unit) == (role, unit)
    assert sparameter_of(name) == name[:3].lower()


def test_vna_sweep_reads_the_parameter_chosen(tmp_path):
    # the last block of the script's file, ending in ENDOFFILE
    path = _write(tmp_path, _VNA_HEAD + _VNA_ROWS + "ENDOFFILE\n", "vna.csv")
    data, notes = _load(path, parameter="S21", freq_unit="Hz")
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([75e9, 75.05e9, 75.1e9]),
                               rtol=1e-15)
    np.testing.assert_allclose(data.response, _S21, rtol=1e-13)
    np.testing.assert_allclose(data.response[0], 0.030525192699 - 0.001517171868j, rtol=1e-9)
    assert any("skipped 1 line(s) after the data (line 11, the first 'ENDOFFILE')" in n
               for n in notes)
    s11, _ = _load(path, parameter="S11", freq_unit="Hz")
    np.testing.assert_allclose(s11.response[0], _polar(-15.2499778591, 111.351589345),
                               rtol=1e-13)


def test_vna_file_of_repeated_blocks_names_the_second(tmp_path):
    path = _write(tmp_path, (_VNA_HEAD + _VNA_ROWS) * 3 + "ENDOFFILE\n", "vna40.csv")
    # the second block's HEADER line is line 11 (7 header lines, 3 rows), its data on 18
    msg = (r"line 11 starts a second block \(a header repeated before each of 3 blocks: "
           r"'HEADER,Raster Number, RF Direction,Po\.\.\.' and 6 more line\(s\), then data "
           r"again from line 18\): this reader reads one sweep: cut the file to one block "
           r"\(the first is lines 8-10\)")
    with pytest.raises(DataError, match=msg):
        _load(path, parameter="S21", freq_unit="Hz")
    with pytest.raises(DataError, match=msg):
        _load(path, columns="freq_hz,skip,skip,mag_db,phase_deg,skip,skip,skip,skip")


def test_two_sweeps_under_one_repeated_header_line(tmp_path):
    # the bad line has as many cells as the data: the block, not 'Freq', is named
    text = "Freq (Hz),S21dB,S21deg\n10,-3,-45\n20,-6,-60\n30,-9,-70\n" * 2
    with pytest.raises(DataError, match=r"line 5 starts a second block \('Freq \(Hz\),"
                       r"S21dB,S21deg', then data again from line 6\).*the first is "
                       r"lines 2-4"):
        fc.load(_write(tmp_path, text, "two.csv"))


def test_one_stray_line_amid_the_data_is_no_block(tmp_path):
    text = "f [Hz],re,im\n1,2,3\noverload\n4,5,6\n7,8,9\n10,11,12\n"
    with pytest.raises(DataError, match=r"line 3: expected 3 columns \(f \[Hz\],re,im\), "
                       r"got 1$"):
        fc.load(_write(tmp_path, text, "stray.csv"))


# --------------------------------------------------------------------------- languages

@pytest.mark.parametrize("header", [
    "Frequenz (Hz);Betrag (dB);Phase (°)", "Frecuencia (Hz);Amplitud (dB);Fase (deg)",
    "Fréquence (Hz);Amplitude (dB);Phase (deg)", "Frequenza (Hz);Ampiezza (dB);Fase (deg)",
    "Frequence (Hz);Verstärkung (dB);Phase (deg)"])
def test_frequency_and_response_named_in_other_languages(tmp_path, header):
    # a European spreadsheet's export: semicolons and decimal commas
    text = header + "\n100;-3,01;-45\n1000;-20;-84,3\n"
    data = fc.load(_write(tmp_path, text, "de.csv"))
    np.testing.assert_allclose(data.omega, [200 * np.pi, 2000 * np.pi], rtol=1e-15)
    np.testing.assert_allclose(data.response, _polar([-3.01, -20.0], [-45.0, -84.3]),
                               rtol=1e-13)
    np.testing.assert_allclose(data.response[0], 0.50001727 - 0.50001727j, rtol=1e-7)


# --------------------------------------------------------------------------- headerless

def test_headerless_file_gets_an_example_with_as_many_names_as_columns(tmp_path):
    text = ("100.000000\t-4.405273\t0.602194\t-1.400000\n"
            "109.647820\t-4.405273\t0.602194\t-1.500000\n"
            "120.226443\t-4.405273\t0.602194\t-1.700000\n")
    path = _write(tmp_path, text, "bode_5d.txt", newline="\r\n")
    with pytest.raises(DataError, match=r"has no header and 4 columns.*e\.g\. "
                       r"columns='freq_hz,mag_db,phase_deg,skip',"):
        fc.load(path)
    data = fc.load(path, columns="freq_hz,mag_db,skip,phase_deg")
    np.testing.assert_allclose(data.response, _polar([-4.405273] * 3, [-1.4, -1.5, -1.7]),
                               rtol=1e-13)


# --------------------------------------------------------------------------- WaveForms

def test_waveforms_impedance_export_reads_as_written(tmp_path):
    text = ("Frequency (Hz),Trace th (*),Trace |Z| (Ohm)\n"
            "10000,3.194523602448248,79106.11056894604\n"
            "10154.6899243308,3.244898068907912,79082.6218579774\n"
            "10311.77274593055,3.284067813252719,79081.06708017744\n")
    data = fc.load(_write(tmp_path, text, "Zin.csv"))
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array(
        [10000, 10154.6899243308, 10311.77274593055]), rtol=1e-15)
    mag = np.array([79106.11056894604, 79082.6218579774, 79081.06708017744])
    deg = np.array([3.194523602448248, 3.244898068907912, 3.284067813252719])
    np.testing.assert_allclose(data.response, mag * np.exp(1j * np.deg2rad(deg)),
                               rtol=1e-14)
    np.testing.assert_allclose(data.response[0], 78983.1871966 + 4408.2728609j, rtol=1e-10)


@pytest.mark.parametrize("name, role, unit", [
    ("Trace θ (°)", "phase", "deg"), ("theta (rad)", "phase", "rad"),
    ("|H|", "mag", "lin"), ("|Y| (S)", "mag", "lin"), ("|Z| (dB)", "mag", "db")])
def test_impedance_names(name, role, unit):
    col = recognise(name)
    assert (col.role, col.unit) == (role, unit)


@pytest.mark.parametrize("name, role, unit, negated", [
    ("Re(Z)/Ohm", "re", None, False), ("-Im(Z)/Ohm", "im", None, True),
    ("|Z|/Ohm", "mag", "lin", False), ("Phase(Z)/deg", "phase", "deg", False),
    ("Zreal", "re", None, False), ("Zimag", "im", None, False), ("Zmod", "mag", "lin", False),
    ("Zphz", "phase", "deg", False), ("Z'", "re", None, False), ("Z''", "im", None, False),
    ("-Z'' (Ω)", "im", None, True), ('"-Z\'\'"', "im", None, True),
    ("-Phase (°)", "phase", "deg", True), ("\u2212phase [rad]", "phase", "rad", True),
    ("-im", "im", None, True), ("TR1: -Phase (deg)", "phase", "deg", True)])
def test_impedance_analysers_names_and_negated_columns(name, role, unit, negated):
    # EC-Lab, Gamry, ZView and Autolab name the impedance's parts their own way, and write
    # -Im(Z) or -Phase (a capacitive impedance then reads positive): the reader negates
    # them back
    col = recognise(name)
    assert (col.role, col.unit, col.negated) == (role, unit, negated)


@pytest.mark.parametrize("name", ["-freq", "-mag", "-3dB", "-Zmod", "Zoom"])
def test_a_minus_before_what_cannot_be_negated_is_no_column(name):
    assert recognise(name) is None


@pytest.mark.parametrize("header, columns", [
    ("freq/Hz,Re(Z)/Ohm,-Im(Z)/Ohm", None), ("f,re,im", "freq_hz,re,-im"),
    ("Frequency (Hz),|Z| (Ohm),-Phase (°)", None)])
def test_a_negated_column_is_read_back_with_its_sign(tmp_path, header, columns):
    # a capacitive impedance: 645.5 - 90.6j Ohm at 1 Hz, written as -Im(Z) = +90.6 (or
    # -phase = +7.99 deg): read as written it would be conjugated
    z = np.array([645.5 - 90.6j, 600.0 - 80.0j, 550.0 - 70.0j])
    if "Phase" in header:
        rows = [(abs(v), -np.degrees(np.angle(v))) for v in z]
    else:
        rows = [(v.real, -v.imag) for v in z]
    text = header + "\n" + "".join(f"{k + 1},{float(a)!r},{float(b)!r}\n"
                                    for k, (a, b) in enumerate(rows))
    data = fc.load(_write(tmp_path, text, "z.csv"), columns=columns, freq_unit="Hz")
    np.testing.assert_allclose(data.response, z, rtol=1e-12)


# --------------------------------------------------------------------------- 4294A

def _hp_block(trace, fmt, rows):
    """One trace block of the 4294A's ASCII save: its two key lines, a blank line, the
    quoted header and tab-separated rows (Imag 0 for a scalar trace)."""
    return (f'\n\n"TRACE: {trace}"\n"FORMAT: {fmt}"\n\n'
            '"Frequency"\t"Data Trace Real"\t"Data Trace Imag"\n'
            + "".join(f"{f:.11e}\t{re:.6e}\t{im:.6e}\n" for f, re, im in rows))


def _hp(parameter="IMPEDANCE MAG PHASE (DEG)", a=("LOG", None), b=("LINEAR", None),
        freqs_b=None):
    """A 4294A export of two traces at 1000, 1008.683 and 1017.441 Hz: |Z| in trace A,
    theta in degrees in trace B unless told otherwise (``a``, ``b``: FORMAT and rows)."""
    f = [1.0e3, 1.008683e3, 1.017441e3]
    rows_a = a[1] or [(x, v, 0.0) for x, v in zip(f, (1.324238, 1.334925, 1.346243))]
    rows_b = b[1] or [(x, v, 0.0) for x, v in zip(freqs_b or f, (75.85065, 75.9645,
                                                                76.08051))]
    return ('4294A REV1.11\n"DATE: Jan 25 2018"\n\n\n'
            f'"MEASURE PARAMETER: {parameter}"\n'
            '"ADAPTER: NONE"\n"SWEEP TYPE: LOG FREQ"\n"NUMBER of POINTS: 3"\n'
            '"POINT DELAY TIME:  0 Sec"\n"SWEEP DELAY TIME:  0 Sec"\n'
            '"OSC LEVEL:  500 mVolt"\n"DC BIAS: OFF"\n"BW: 5"\n'
            '"SWEEP AVERAGING: OFF"\n"POINT AVERAGING: OFF"\n'
            + _hp_block("A", a[0], rows_a) + _hp_block("B", b[0], rows_b))


_HP_F = 2 * np.pi * np.array([1.0e3, 1.008683e3, 1.017441e3])
_HP_Z = np.array([1.324238, 1.334925, 1.346243]) * np.exp(
    1j * np.deg2rad([75.85065, 75.9645, 76.08051]))


def test_hp4294a_two_traces_are_one_impedance(tmp_path):
    # |Z| in trace A (FORMAT LOG is the axis's scale), theta in degrees in trace B, as the
    # measure parameter says; the published export of this layout was refused with
    # "column 'Data Trace Real' is not a known name"
    path = _write(tmp_path, _hp(), "hp4294a.txt")
    assert path.endswith("hp4294a.txt")
    data, notes = _load(path)
    np.testing.assert_allclose(data.omega, _HP_F, rtol=1e-15)
    np.testing.assert_allclose(data.response, _HP_Z, rtol=1e-14)
    # 1.324238 ohm at 75.85065 degrees, at 1 kHz, by hand
    np.testing.assert_allclose(data.response[0], 0.32371037 + 1.28406304j, rtol=1e-7)
    assert data.name == "hp4294a"
    assert notes == ["'" + path + "': read trace A (lines 22-24) as the magnitude and trace "
                     "B (lines 31-33) as the phase in degrees, as its line 'MEASURE "
                     "PARAMETER: IMPEDANCE MAG PHASE (DEG)' says"]
    # the same in a band, and through the command line's reader (CRLF line ends)
    data, _ = _load(path, band=(1005, 1020))
    np.testing.assert_allclose(data.response, _HP_Z[1:], rtol=1e-14)
    crlf = _write(tmp_path, _hp(), "crlf.txt", newline="\r\n")
    np.testing.assert_allclose(_load(crlf)[0].response, _HP_Z, rtol=1e-14)


def test_hp4294a_phase_in_radians_and_resistance_reactance(tmp_path):
    rad = [(f, np.deg2rad(d), 0.0) for f, d in zip(_HP_F / (2 * np.pi),
                                                   (75.85065, 75.9645, 76.08051))]
    path = _write(tmp_path, _hp("IMPEDANCE MAG PHASE (RAD)", b=("LINEAR", rad)), "rad.txt")
    np.testing.assert_allclose(_load(path)[0].response, _HP_Z, rtol=1e-6)   # 7 digits
    # R in trace A, X in trace B (a measure parameter R-X, as the 4294A's key names it)
    r = [(f, z.real, 0.0) for f, z in zip(_HP_F / (2 * np.pi), _HP_Z)]
    x = [(f, z.imag, 0.0) for f, z in zip(_HP_F / (2 * np.pi), _HP_Z)]
    path = _write(tmp_path, _hp("R-X", a=("LINEAR", r), b=("LINEAR", x)), "rx.txt")
    data, notes = _load(path)
    np.testing.assert_allclose(data.response, _HP_Z, rtol=1e-6)
    assert "as the real part and trace B (lines 31-33) as the imaginary part" in notes[0]


def test_trace_formats_log_magnitude_and_phase(tmp_path):
    # a network analyser's two traces, FORMAT LOG MAG (dB) and PHASE (degrees); the
    # formats say what each holds, the measure parameter (a ratio) does not
    db = [(f, 20 * np.log10(abs(z)), 0.0) for f, z in zip(_HP_F / (2 * np.pi), _HP_Z)]
    deg = [(f, np.degrees(np.angle(z)), 0.0) for f, z in zip(_HP_F / (2 * np.pi), _HP_Z)]
    path = _write(tmp_path, _hp("B/R", a=("LOG MAG", db), b=("PHASE", deg)), "vna.txt")
    data, notes = _load(path)
    np.testing.assert_allclose(data.response, _HP_Z, rtol=1e-6)
    assert ("as the magnitude in dB and trace B (lines 31-33) as the phase in degrees, as "
            "their FORMAT lines ('LOG MAG', 'PHASE') say") in notes[0]


def test_traces_of_different_sweeps_are_refused(tmp_path):
    path = _write(tmp_path, _hp(freqs_b=[1.0e3, 1.008683e3, 1.02e3]), "two.txt")
    with pytest.raises(DataError, match=r"the traces' frequencies differ: 1017\.441 on line "
                       r"24 \(trace A\), 1020 on line 33 \(trace B\); the two traces must be "
                       r"of one sweep"):
        _load(path)
    short = _hp(b=("LINEAR", [(1.0e3, 75.85065, 0.0), (1.008683e3, 75.9645, 0.0)]))
    with pytest.raises(DataError, match=r"trace A has 3 points \(lines 22-24\), trace B 2 "
                       r"\(lines 31-32\): the two traces must be of one sweep"):
        _load(_write(tmp_path, short, "short.txt"))


def test_traces_the_header_does_not_name_need_columns(tmp_path):
    # a measure parameter of derived quantities names neither trace a part of the response
    path = _write(tmp_path, _hp("Ls-Rs"), "ls.txt")
    with pytest.raises(DataError, match=r"holds two traces of scalar quantities \(trace A, "
                       r"lines 22-24; trace B, lines 31-33\), and its key lines \(trace A: "
                       r"FORMAT 'LOG'; trace B: FORMAT 'LINEAR'; measure parameter 'Ls-Rs'\) "
                       r"do not say which is which: pass columns="):
        _load(path)
    data, notes = _load(path, columns="freq_hz,mag,phase_deg")
    np.testing.assert_allclose(data.response, _HP_Z, rtol=1e-14)
    assert "as columns= says" in notes[0]
    with pytest.raises(OptionError, match=r"name the frequency and each trace in order"):
        _load(path, columns="freq_hz,complex")


def test_hp4294a_columns_that_contradict_the_header_are_refused(tmp_path):
    path = _write(tmp_path, _hp(), "hp4294a.txt")
    with pytest.raises(DataError, match=r"columns= reads trace A as the real part and trace B "
                       r"as the imaginary part, but its line 'MEASURE PARAMETER: IMPEDANCE "
                       r"MAG PHASE \(DEG\)' says they are the magnitude and the phase in "
                       r"degrees: drop columns="):
        _load(path, columns="freq_hz,re,im")
    np.testing.assert_allclose(_load(path, columns="freq_hz,mag,phase")[0].response, _HP_Z,
                               rtol=1e-14)
    with pytest.raises(OptionError, match=r"parameter= does not apply"):
        _load(path, parameter="S21")


def test_a_phase_beyond_a_turn_is_not_the_phase(tmp_path):
    # theta written in degrees under a measure parameter that says radians
    path = _write(tmp_path, _hp("IMPEDANCE MAG PHASE (RAD)"), "bad.txt")
    with pytest.raises(DataError, match=r"line 31: trace B holds 75\.8507, more than a turn "
                       r"for a phase in rad"):
        _load(path)


def test_one_trace_block(tmp_path):
    # a complex trace (COMPLEX Z-Y, FORMAT COMPLEX) fills Real and Imag: it is the response
    rows = [(f, z.real, z.imag) for f, z in zip(_HP_F / (2 * np.pi), _HP_Z)]
    text = _hp("COMPLEX Z-Y", a=("COMPLEX", rows)).split('\n\n\n"TRACE: B"')[0] + "\n"
    data, _ = _load(_write(tmp_path, text, "z.txt"))
    np.testing.assert_allclose(data.omega, _HP_F, rtol=1e-15)
    np.testing.assert_allclose(data.response, _HP_Z, rtol=1e-6)
    # a scalar one (|Z| alone) is half a response
    text = _hp().split('\n\n\n"TRACE: B"')[0] + "\n"
    with pytest.raises(DataError, match=r"holds one trace, of a scalar quantity \(trace A "
                       r"\(lines 22-24, FORMAT 'LOG'\): its Imag column is 0\): a response "
                       r"needs two"):
        _load(_write(tmp_path, text, "mag.txt"))
    # a sweep of the DC bias, not of frequency
    text = _hp().replace('"Frequency"', '"DC Bias"')
    with pytest.raises(DataError, match=r"line 21: the first column of trace A is 'DC Bias', "
                       r"not a frequency: the analyser swept another quantity"):
        _load(_write(tmp_path, text, "bias.txt"))


def test_loudspeaker_frd_and_zma_files_follow_their_convention(tmp_path):
    # published loudspeaker data: .frd is Hz, dB, degrees; .zma Hz, ohms, degrees, both
    # without a header (a .zma may open with '*' comment lines); they were read as
    # frequency, real, imaginary (-57.66 - 284.6j for -57.66 dB at 75.4 degrees)
    frd = tmp_path / "F144OB.frd"
    frd.write_text("0  -80.000  0.00\n5  -57.663  -284.60\n10  -45.100  -250.00\n")
    zma = tmp_path / "L16.zma"
    zma.write_text("* Data: Impedance (ohms), Phase (degrees)\n*\n"
                   "10.000 +7.1929 +25.7824\n20.000 +9.5000 +40.0000\n30.0 12.0 10.0\n")
    with pytest.warns(DataWarning, match=r"no header: read as freq_hz, mag_db, phase_deg "
                      r"\(the \.frd convention\)"):
        d = fc.load(frd)
    assert d.n_points == 2 and d.omega[0] == pytest.approx(2 * np.pi * 5)
    assert abs(d.response[0]) == pytest.approx(10 ** (-57.663 / 20), rel=1e-12)
    assert np.degrees(np.angle(d.response[0])) == pytest.approx(-284.60 + 360, rel=1e-12)
    with pytest.warns(DataWarning, match=r"read as freq_hz, mag, phase_deg \(the \.zma"):
        z = fc.load(zma)
    assert abs(z.response[0]) == pytest.approx(7.1929, rel=1e-12)
    assert np.degrees(np.angle(z.response[0])) == pytest.approx(25.7824, rel=1e-12)
    # columns= still decides
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        ri = fc.load(zma, columns="freq_hz,re,im")
    assert ri.response[0] == pytest.approx(7.1929 + 25.7824j)


def test_a_pulse_ascii_export_index_column_and_footer(tmp_path):
    # a Brueel & Kjaer PULSE LabShop ASCII export: index, frequency, value rows between a
    # preamble and a 7-line footer (TagsBegin: ... TagScalesEnd:); read as frequency, real,
    # imaginary the index became the frequency
    rows = "".join(f"{k}\t {k - 1.0:.10e}\t {1e-9 * (1 + k % 3):.5e}\n" for k in range(1, 40))
    footer = ("TagsBegin:\t \t \nOverLoad:\t \tFalse\nAverageNumber: []\t \t 1.00000e+001\n"
              "OverLoadRatio: []\t \t 1.19209e-007\nTagsEnd:\t \t \nTagScalesBegin:\t \t \n"
              "TagScalesEnd:\t \t \n")
    path = tmp_path / "pls1.txt"
    head = "".join(f"{k}:\t{v}\t \n" for k, v in (
        ("Header Size", " 12"), ("Decimal Symbol", "."), ("Data Type", "Real"),
        ("X-Axis type", "Linear"), ("X-Axis size", "39"), ("X-Axis unit", "Hz"),
        ("X-Axis first value", " 0.0000000000e+000"), ("X-Axis delta", " 1.0e+000"),
        ("AmplitudeUnit", "V"), ("Analyzer", "FFT_Spectrum_Averaging")))
    path.write_text(head + "\t \t \nZ-index:\t \t1\nDate:\t \t2018/7/5\n" + rows + footer)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        with pytest.raises(DataError, match=r"the first column counts the rows \(1\.\.39\): "
                           r"an index, not a frequency"):
            fc.load(path, freq_unit="Hz")
        with pytest.raises(OptionError, match="the columns must be one frequency and "
                           "real\\+imaginary, magnitude\\+phase or one complex column"):
            fc.load(path, columns="skip,freq_hz,mag")
    with pytest.warns(DataWarning, match=r"skipped 7 line\(s\) after the data"):
        with pytest.raises(DataError):
            fc.load(path, freq_unit="Hz")


def test_both_missing_units_are_named_at_once(tmp_path):
    # a driver maker's 'Freq dB Phase' export: the frequency's unit and then, on the next
    # try, the phase's were asked for one at a time
    path = tmp_path / "TW022.txt"
    path.write_text("Freq dB Phase\n200 67.64 162.82\n250 68.1 150.2\n")
    with pytest.raises(DataError, match=r"column 'Freq' has no unit\).*; the phase column "
                       r"'Phase' does not give its unit either: name it phase_deg"):
        fc.load(path)


def test_a_headerless_third_column_that_wraps_as_degrees_is_not_read_as_imaginary(tmp_path):
    # a lab's hand-typed Bode table (Hz, dB, degrees) without a header: with freq_unit it
    # was read as real and imaginary parts (6.8 dB at 75 degrees became 6.8 + 75j)
    f = np.arange(10.0, 600.0, 10.0)
    deg = (75.0 - 0.6 * f + 180.0) % 360.0 - 180.0            # wraps from -177 to 178
    path = tmp_path / "bode.txt"
    path.write_text("".join(f"{a:g},{20 - a / 50:.3g},{p:.4g}\n" for a, p in zip(f, deg)))
    with pytest.raises(DataError, match=r"no header, and the third column stays within "
                       r"\+-180 and jumps from -177 to 177 between data rows 42 and 43, as a "
                       r"phase in degrees wraps: name the columns, e.g. columns='freq_hz,"
                       r"mag_db,phase_deg'"):
        fc.load(path, freq_unit="Hz")
    data = fc.load(path, columns="freq_hz,mag_db,phase_deg")
    np.testing.assert_allclose(np.degrees(np.angle(data.response)), deg, atol=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        assert fc.load(path, columns="f,re,im", freq_unit="Hz").response[0] == 19.8 + 69j
    # real and imaginary parts that stay within +-180 but do not jump are read as before
    path.write_text("".join(f"{a:g},{-a / 5:g},{a / 4:g}\n" for a in f))
    with pytest.warns(DataWarning, match="no header: read the columns as frequency, real, "
                      "imaginary"):
        assert fc.load(path, freq_unit="Hz").response[-1] == -118 + 147.5j


def test_a_magnitude_alone_and_a_complex_column_of_imaginary_parts_are_explained(tmp_path):
    # a microphone calibration file (Hz, dB): columns= naming them said only which
    # layouts are allowed; a script's 'freq (Hz), real, complex' table whose 'complex'
    # column holds the imaginary parts
    mic = tmp_path / "mic.txt"
    mic.write_text("20 -0.5\n40 -0.2\n80 0.0\n")
    with pytest.raises(OptionError, match=r"got freq, mag; a magnitude alone cannot be "
                       r"fitted: the model's delay and zeros need the phase too"):
        fc.load(mic, columns="freq_hz,mag_db")
    tsv = tmp_path / "fake.tsv"
    tsv.write_text("freq (Hz)\treal\tcomplex\n1.0\t0.5\t-0.1\n2.0\t0.4\t-0.2\n")
    with pytest.raises(DataError, match=r"if the column read as 'complex' holds the imaginary "
                       r"parts, name it im \(columns='freq_hz,re,im'\)"):
        fc.load(tsv)
    assert fc.load(tsv, columns="freq_hz,re,im").response[1] == 0.4 - 0.2j


@pytest.mark.parametrize("text, first", [
    # an acoustics program's export of impulse responses: the header in a comment
    ("#\n# Measurement exported using HOLM Acoustics software\n# Samplerate: 44100\n#\n"
     "## sample,0 (F144/W_0d_0) ,1 (F144/W_0d_1) \n-2,1e-8,2e-7\n-1,4e-7,-1e-7\n0,0.5,0.4\n",
     "sample"),
    ("time,u,y\n0,1,2\n0.001,2,3\n0.002,3,4\n", "time"),
    ("t [s];force;accel\n0;1;2\n0,001;2;3\n", "t [s]"),
])
def test_a_table_of_time_samples_is_refused_as_such(tmp_path, text, first):
    # it was refused as 'no header and 10 columns: cannot tell what they are' or as an
    # unknown column name, with columns= examples for a frequency response
    path = tmp_path / "rec.txt"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        with pytest.raises(DataError, match=rf"holds time-domain samples, not a frequency "
                           rf"response: its first column '{re.escape(first)}' counts time "
                           r".*freqid frf FILE --input NAME --output NAME"):
            fc.load(path)


# ------------------------------------------------------------------ impedance analysers

_EIS_Z = np.array([59.89103 - 11.25287j, 58.61285 - 0.965082j, 57.35844 - 14.09869j])
_EIS_F = np.array([100019.5, 79511.72, 63105.47])


def test_gamry_table_with_leading_tabs_and_its_units_line_reads_as_written(tmp_path):
    # a Gamry Framework .DTA: metadata lines, 'ZCURVE TABLE', a header and a units line
    # that begin with a tab (the units line's first cell '#'), columns the reader does
    # not know around Freq, Zreal, Zimag, Zmod and Zphz (degrees); the sweep descends
    rows = "".join(
        f"\t{k}\t{7 + k}\t{f!r}\t{z.real!r}\t{z.imag!r}\t1\t{abs(z)!r}\t"
        f"{float(np.degrees(np.angle(z)))!r}\t-1.4E-006\t-0.0006\t9\t0.0001651\t0.01"
        "\t1395.2\n" for k, (f, z) in enumerate(zip(_EIS_F.tolist(), _EIS_Z.tolist())))
    text = ("EXPLAIN\nTAG\tEISPOT\nTITLE\tLABEL\tPotentiostatic EIS\tTest Identifier\n"
            "VFREQ\tQUANT\t100000\tInitial Freq. (Hz)\nZCURVE\tTABLE\n"
            "\tPt\tTime\tFreq\tZreal\tZimag\tZsig\tZmod\tZphz\tIdc\tVdc\tIERange\tImod"
            "\tVmod\tTemp\n\t#\ts\tHz\tohm\tohm\tV\tohm\t\u00b0\tA\tV\t#\tA\tV\t\u00b0C\n"
            + rows)
    path = tmp_path / "eis.DTA"
    path.write_bytes(text.encode("cp1252"))
    data, notes = _load(str(path))
    np.testing.assert_allclose(data.omega, 2 * np.pi * _EIS_F[::-1], rtol=1e-15)
    np.testing.assert_allclose(data.response, _EIS_Z[::-1], rtol=1e-15)
    assert any("left out columns of names the reader does not know: 'Pt', 'Time', "
               "'Zsig'" in n for n in notes)
    assert any("columns 'Zmod', 'Zphz' give the same response" in n for n in notes)


def test_ec_lab_and_zplot_exports_read_as_written(tmp_path):
    # EC-Lab's -Im(Z) beside |Z| and Phase(Z) (checked against the parts); ZPlot's header
    # followed by its 'End Comments' line before the data
    z = _EIS_Z
    lab = ("EC-Lab ASCII FILE\nNb header lines : 4\n\n"
           "freq/Hz\tRe(Z)/Ohm\t-Im(Z)/Ohm\t|Z|/Ohm\tPhase(Z)/deg\ttime/s\tcycle number\t\n"
           + "".join(f"{f:.7E}\t{v.real:.7E}\t{-v.imag:.7E}\t{abs(v):.7E}\t"
                     f"{np.degrees(np.angle(v)):.7E}\t0.78\t1.0\t\n"
                     for f, v in zip(_EIS_F, z)))
    data, notes = _load(_write(tmp_path, lab, "eis.mpt"))
    np.testing.assert_allclose(data.response, z[::-1], rtol=1e-7)
    zplot = ("ZPLOT2 ASCII\n  Data Points:                3\n"
             "  Freq(Hz)\tAmpl\tBias\tTime(Sec)\tZ'(a)\tZ''(b)\tGD\tErr\tRange\n"
             "End Comments\n" + "".join(
                 f"{f:.6E}\t1.0000E-02\t0.0000E+00\t2.67\t{v.real:.4E}\t{v.imag:.4E}\t0\t0\t3\n"
                 for f, v in zip(_EIS_F, z)))
    data, notes = _load(_write(tmp_path, zplot, "eis.z"))
    assert any("skipped line(s) 4 ('End Comments') between the header and the data" in n
               for n in notes)
    np.testing.assert_allclose(data.omega, 2 * np.pi * _EIS_F[::-1], rtol=1e-6)
    np.testing.assert_allclose(data.response, z[::-1], rtol=1e-4)


def test_degrees_in_a_column_said_to_be_radians_are_refused(tmp_path):
    # a phase in degrees under the header phase_rad read as radians gave a fit at RMS 1
    # ("check the data"): values within +-180 that jump by 356 between two rows are
    # degrees wrapping
    f = np.array([10.0, 20.0, 30.0, 40.0])
    deg = np.array([-170.0, -178.0, 178.0, 170.0])
    text = "freq_hz,mag_db,phase_rad\n"
    text += "".join(f"{a!r},-3.0,{b!r}\n" for a, b in zip(f.tolist(), deg.tolist()))
    path = _write(tmp_path, text, "m.csv")
    with pytest.raises(DataError, match=r"column 'phase_rad' is read in radians, but its "
                       r"values wrap as a phase in degrees does \(-178 then 178 on lines 3 "
                       r"and 4, all within \+-180\); if it is in degrees, pass "
                       r"columns='freq_hz,mag_db,phase_deg'"):
        fc.load(path)
    # an unwrapped phase in radians beyond a turn is no such thing
    text = "freq_hz,mag_db,phase_rad\n" + "".join(
        f"{a!r},-3.0,{-2.0 * a!r}\n" for a in f.tolist())
    data = fc.load(_write(tmp_path, text, "r.csv"))
    np.testing.assert_allclose(data.response, 10 ** (-3 / 20) * np.exp(-2j * f), rtol=1e-12)


# ------------------------------------------------------------------- field solvers

@pytest.mark.parametrize("label, scale", [
    ("Freq [MHz]", 1e6), ("Freq [GHz]", 1e9), ("f/kHz", 1e3), ("Frequency (mHz)", 1e-3),
    ("F [THz]", 1e12), ("Freq [Hz]", 1.0)])
def test_frequency_units_with_a_prefix(label, scale):
    # Ansys exports 'Freq [GHz]'; an impedance analyser may write mHz (milli, not mega)
    col = recognise(label)
    assert (col.role, col.unit, col.scale) == ("freq", "hz", scale)


def test_ansys_exports_read_as_written(tmp_path):
    # an Ansys Circuit/Designer CSV: frequencies in GHz or MHz, each column a function of
    # a quantity whose name holds the separator inside its quotes; of several quantities,
    # parameter= reads one and load_all each
    one = ('"Freq [GHz]","dB(S(Port1,Port2)) []","ang_deg(S(Port1,Port2)) [deg]"\n'
           "1,-3.0,-10\n1.1,-3.2,-20\n1.2,-3.5,-30\n")
    data = fc.load(_write(tmp_path, one, "s.csv"))
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([1.0, 1.1, 1.2]) * 1e9,
                               rtol=1e-15)
    np.testing.assert_allclose(data.response, _polar([-3.0, -3.2, -3.5], [-10, -20, -30]),
                               rtol=1e-14)
    two = ('"Freq [MHz]","mag(V(V1)) [V]","mag(V(V2)) [V]","ang_deg(V(V1)) [deg]",'
           '"ang_deg(V(V2)) [deg]"\n10,19.34,20.85,-10.64,-9.28\n50,7.50,12.52,-29.85,-44.23\n'
           "100,3.1,5.2,-60.1,-80.3\n")
    path = _write(tmp_path, two, "v.csv")
    with pytest.raises(DataError, match=r"its columns give 2 quantities \(V\(V1\), V\(V2\)\): "
                       r"pass parameter='V\(V1\)'"):
        fc.load(path)
    v2 = fc.load(path, parameter="V(V2)")
    np.testing.assert_allclose(v2.omega, 2 * np.pi * np.array([10.0, 50.0, 100.0]) * 1e6)
    np.testing.assert_allclose(v2.response, np.array([20.85, 12.52, 5.2]) * np.exp(
        1j * np.deg2rad([-9.28, -44.23, -80.3])), rtol=1e-14)
    assert [d.name for d in fc.load_all(path)] == ["V(V1)", "V(V2)"]


def test_a_table_of_repeated_sweeps_reads_one_with_record(tmp_path):
    # an EC-Lab export of 3 cycles, each a descending sweep: the unsorted-rows error
    # ("sort the file") had pointed at the wrong cause; each sweep reads with record=
    f = np.array([1000.0, 100.0, 10.0, 1.0])
    z = [(60.0 - 1.0j) * (k + 1) for k in range(3)]
    text = "freq/Hz\tRe(Z)/Ohm\t-Im(Z)/Ohm\tcycle number\n" + "".join(
        f"{a!r}\t{zk.real * (1 + a / 1e4)!r}\t{-zk.imag!r}\t{k + 1}\n"
        for k, zk in enumerate(z) for a in f.tolist())
    path = _write(tmp_path, text, "cycles.mpt")
    with pytest.raises(DataError, match=r"holds 3 sweeps one after another \(the frequency "
                       r"starts again on line\(s\) 6, 10\): pass record=0..2 to load\(\) "
                       r"\(command line --record K\) to read one sweep"):
        fc.load(path)
    for k in range(3):
        data = fc.load(path, record=k)
        np.testing.assert_allclose(data.omega, 2 * np.pi * f[::-1])
        np.testing.assert_allclose(data.response, z[k].real * (1 + f[::-1] / 1e4)
                                   + 1j * z[k].imag, rtol=1e-15)
    with pytest.raises(OptionError, match=r"record=3 is out of range: .* holds 3 sweeps"):
        fc.load(path, record=3)
    one = _write(tmp_path, text.split("\n", 5)[0] + "\n" + "\n".join(
        text.split("\n")[1:5]) + "\n", "one.mpt")
    with pytest.raises(OptionError, match=r"record=0 chooses .* a sweep of a table of "
                       r"several; .* has none: drop it"):
        fc.load(one, record=0)
    # rows out of order by a small step are no sweeps: the unsorted-rows error stands
    bad = _write(tmp_path, "freq_hz,re,im\n1,1,0\n2,1,0\n3,1,0\n2.9,1,0\n4,1,0\n5,1,0\n6,1,0\n",
                 "bad.csv")
    with pytest.raises(DataError, match="unsorted rows"):
        fc.load(bad)


@pytest.mark.parametrize("text, what, how", [
    ("# Created Thu Jan 13 12:23:22 2022\n\nCITIFILE A.01.00\nNAME Sweep1.SP1.SP\n"
     "VAR freq MAG 2\nDATA S[1,1] MAGANGLE\nVAR_LIST_BEGIN\n7.1e8\n7.15e8\nVAR_LIST_END\n"
     "BEGIN\n0.99,-0.01\n0.98,-0.02\nEND\n", "a CITIfile", r"skrf\.io\.citi\.Citi\(path\)"),
    ("! Created\nVAR Cm(real) =       7e-16\nBEGIN Sweep1.SP1.SP\n"
     "% freq(real) S[1,1](complex)\n 710000000 0.99 -0.01\n 715000000 0.98 -0.02\nEND\n",
     "an MDIF file", r"skrf\.io\.mdif\.Mdif\(path\)"),
    ("<Qucs Dataset 0.0.15>\n<indep frequency 2>\n  +7.5e+10\n  +7.6e+10\n</indep>\n",
     "a Qucs dataset", "export the data from Qucs")])
def test_simulators_data_formats_are_named_with_their_conversion(tmp_path, text, what, how):
    # a CITIfile's 'DATA S[1,1] MAGANGLE' line had been called its header, with advice to
    # pass columns=, which no columns= can follow
    with pytest.raises(DataError, match=rf"is {what} .*, not a table the readers parse; "
                       rf".*{how}" if what != "a Qucs dataset" else
                       rf"is {what}, not a table the readers parse; {how}"):
        fc.load(_write(tmp_path, text, "sim.dat"))


def test_review_cases_of_the_readers_new_rules(tmp_path):
    # a magnitude named as a complex quantity beside a phase of a name the reader did not
    # know: the phase (Keysight's θz) is read, not left out with Z read as real numbers
    data = fc.load(_write(tmp_path, "Frequency(Hz),Z(Ohm),\u03b8z(\u00b0)\n10,10,-30\n"
                                    "20,5,-40\n30,4,-50\n", "z.csv"))
    np.testing.assert_allclose(data.response, np.array([10, 5, 4]) * np.exp(
        1j * np.deg2rad([-30, -40, -50])), rtol=1e-14)
    path = _write(tmp_path, "Freq(Hz),Z(Ohm),Zeta\n10,10,-30\n20,5,-40\n30,4,-50\n", "u.csv")
    with pytest.raises(DataError, match="column 'Zeta' is not a known name"):
        fc.load(path)
    # ZView's double prime written as one '"': no quote opens mid-cell
    data = fc.load(_write(tmp_path, 'Freq(Hz),Z",Z\'\n10,-1,3\n20,-2,3\n30,-3,3\n', "q.csv"))
    np.testing.assert_allclose(data.response, [3 - 1j, 3 - 2j, 3 - 3j])
    # a first column only sometimes empty keeps its cells (no tab-led table)
    text = "label\tfreq_hz\tre\tim\nstart\t10\t0.1\t-0.1\n\t20\t0.05\t-0.2\n\t30\t0.04\t-0.3\n"
    data = fc.load(_write(tmp_path, text, "t.tsv"), columns="skip,freq_hz,re,im")
    np.testing.assert_allclose(data.response, [0.1 - 0.1j, 0.05 - 0.2j, 0.04 - 0.3j])
    # one point out of order early in a sweep is no second sweep
    path = _write(tmp_path, "freq_hz,re,im\n" + "".join(
        f"{f},1,0\n" for f in (1, 2, 3, 10, 5, 20, 30, 40, 50, 60)), "g.csv")
    with pytest.raises(DataError, match="unsorted rows"):
        fc.load(path)
    # names in an .npz keep their minus and their unit's prefix
    np.savez(tmp_path / "m.npz", **{"Freq [MHz]": [1.0, 2.0, 3.0], "re": [1.0, 2.0, 3.0],
                                    "-Im(Z)": [1.0, 1.0, 1.0]})
    data = fc.load(tmp_path / "m.npz")
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([1e6, 2e6, 3e6]))
    np.testing.assert_allclose(data.response, [1 - 1j, 2 - 1j, 3 - 1j])
    # "- Phase" with a space is negated too; mHz is milli, every other spelling mega
    assert recognise("- Phase (deg)").negated
    assert [recognise(u).scale for u in ("f [mHz]", "f [MHz]", "f [mhz]", "F [MHZ]")] == [
        1e-3, 1e6, 1e6, 1e6]
    with pytest.raises(OptionError, match=r"record must be an integer \(0-based\), got '1'"):
        fc.load(_write(tmp_path, "freq_hz,re,im\n" + "".join(
            f"{f},1,0\n" for f in (1, 2, 3, 1, 2, 3)), "s.csv"), record="1")


def test_a_second_form_never_filled_in_is_left_out_with_a_note(tmp_path):
    # an EC-Lab export whose |Z| and Phase(Z) columns hold 0 in every row: not a second
    # measurement (the error had said so), a column the analyser did not fill
    text = "freq/Hz\tRe(Z)/Ohm\t-Im(Z)/Ohm\t|Z|/Ohm\tPhase(Z)/deg\n" + "".join(
        f"{f}\t{r}\t{i}\t0.0\t0.0\n" for f, r, i in ((1.0, 645.5, 90.6), (10.0, 400.0, 60.0),
                                                   (100.0, 200.0, 30.0)))
    data, notes = _load(_write(tmp_path, text, "e.mpt"))
    np.testing.assert_allclose(data.response, [645.5 - 90.6j, 400 - 60j, 200 - 30j])
    assert any("left out '|Z|/Ohm', 'Phase(Z)/deg', whose values are all 0 (not filled in)"
               in n for n in notes)

"""Touchstone files as published examples and damaged copies show them: version-1 Z/Y/H/G
values normalised to the option line's R (one or one per port), records that are short or
run long, a version-2 file without [Network Data], rows out of frequency order."""

import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.io.loaders import DataWarning

#: The Touchstone 2.0 specification's examples 9 (version 1) and 10 (version 2): one
#: 1-port impedance, normalised to R = 75 ohm in the first, in ohms in the second.
EX_9 = """!1-port Z-parameter file, multiple frequency points
# MHz Z MA R 75
!freq magZ11 angZ11
100 0.99 -4
200 0.80 -22
300 0.707 -45
400 0.40 -62
500 0.01 -89
"""
EX_10 = """[Version] 2.0
# MHz Z MA
[Number of Ports] 1
[Number of Frequencies] 5
[Reference] 20.0
[Network Data]
100 74.25 -4
200 60 -22
300 53.025 -45
400 30 -62
500 0.75 -89
"""
OHMS = np.array([74.25, 60.0, 53.025, 30.0, 0.75]) * np.exp(
    1j * np.deg2rad([-4, -22, -45, -62, -89]))


def _write(tmp_path, text, name):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _quiet_load(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return fc.load(path, **kw)


def test_version_1_impedance_is_denormalised_to_ohms(tmp_path):
    v1 = _quiet_load(_write(tmp_path, EX_9, "ex9.s1p"))
    v2 = _quiet_load(_write(tmp_path, EX_10, "ex10.ts"))
    np.testing.assert_allclose(v1.response, OHMS, rtol=1e-12)   # was 0.99 (stored value)
    np.testing.assert_allclose(v2.response, OHMS, rtol=1e-12)   # version 2: as stored
    np.testing.assert_allclose(v1.omega, 2e6 * np.pi * np.arange(100, 501, 100), rtol=1e-15)
    skrf = pytest.importorskip("skrf")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = skrf.Network(str(tmp_path / "ex9.s1p")).z[:, 0, 0]
    np.testing.assert_allclose(v1.response, ref, rtol=1e-9)


def test_version_1_admittance_is_divided_by_r(tmp_path):
    # y = Y R (normalised admittance): 0.5 + 0.25j at R = 50 is 0.01 + 0.005j siemens
    y1 = _quiet_load(_write(tmp_path, "# MHz Y RI R 50\n100 0.5 0.25\n200 1 0\n", "y.s1p"))
    np.testing.assert_allclose(y1.response, [0.01 + 0.005j, 0.02], rtol=1e-15)
    y2 = _quiet_load(_write(tmp_path, "[Version] 2.0\n# MHz Y RI R 50\n[Number of Ports] 1\n"
                                      "[Network Data]\n100 0.01 0.005\n200 0.02 0\n", "y.ts"))
    np.testing.assert_allclose(y2.response, y1.response, rtol=1e-15)
    with pytest.raises(OptionError, match=r"holds Y11 only \(an input admittance\)"):
        fc.load(tmp_path / "y.s1p", parameter="Y21")
    with pytest.raises(OptionError, match=r"holds Z11 only \(an input impedance\)"):
        fc.load(_write(tmp_path, EX_9, "ex9.s1p"), parameter="Z21")


@pytest.mark.parametrize("kind, expected", [
    # stored h11 h21 h12 h22 (order 11 21 12 22) = 1+1j, 2, 3, 4 at R = 50
    ("H", {"11": 50 + 50j, "21": 2, "12": 3, "22": 0.08}),
    ("G", {"11": 0.02 + 0.02j, "21": 2, "12": 3, "22": 200}),
])
def test_version_1_hybrid_parameters(tmp_path, kind, expected):
    path = _write(tmp_path, f"# GHz {kind} RI R 50\n1 1 1 2 0 3 0 4 0\n2 1 1 2 0 3 0 4 0\n",
                  "h.s2p")
    for p, value in expected.items():
        np.testing.assert_allclose(_quiet_load(path, parameter=kind + p).response,
                                   [value, value], rtol=1e-15)


def test_one_r_per_port(tmp_path):
    rows = "1 1 0 2 0 3 0\n4 0 5 0 6 0\n7 0 8 0 9 0\n"
    z = _write(tmp_path, "# GHz Z RI R 10 20 40\n" + rows, "z.s3p")
    np.testing.assert_allclose(_quiet_load(z, parameter="Z12").response, [2 * np.sqrt(200)])
    np.testing.assert_allclose(_quiet_load(z, parameter="Z33").response, [9 * 40.0])
    y = _write(tmp_path, "# GHz Y RI R 10 20 40\n" + rows, "y.s3p")
    np.testing.assert_allclose(_quiet_load(y, parameter="Y31").response, [7 / 20.0])
    s = _write(tmp_path, "# GHz S RI R 0.01 0.01 50.0\n" + rows, "s.s3p")
    np.testing.assert_array_equal(_quiet_load(s, parameter="S23").response, [6.0])
    with pytest.raises(DataError, match=r"line 1: the option line gives 2 reference "
                       r"resistances for a 3-port file; give one .* or one per port \(3\)"):
        fc.load(_write(tmp_path, "# GHz S RI R 50 50\n" + rows, "two.s3p"), parameter="S21")
    h = _write(tmp_path, "# GHz H RI R 10 20\n1 1 0 2 0 3 0 4 0\n", "h.s2p")
    np.testing.assert_allclose(_quiet_load(h, parameter="H11").response, [10.0])
    np.testing.assert_allclose(_quiet_load(h, parameter="H22").response, [0.2])
    with pytest.raises(DataError, match=r"H21 of a version 1 file with reference "
                       r"resistances 20 and 10 ohm per port is not read"):
        fc.load(h, parameter="H21")


def test_r_without_a_value_or_not_a_number(tmp_path):
    text = "# GHz S RI R\n1 0.5 0.25\n"
    np.testing.assert_array_equal(_quiet_load(_write(tmp_path, text, "a.s1p")).response,
                                  [0.5 + 0.25j])
    z = _write(tmp_path, "# GHz Z RI R\n1 0.5 0.25\n", "z.s1p")
    np.testing.assert_allclose(_quiet_load(z).response, [25 + 12.5j], rtol=1e-15)  # 50 ohm
    s = _write(tmp_path, "# GHz S RI R (50+50j)\n1 0.5 0.25\n", "c.s1p")
    np.testing.assert_array_equal(_quiet_load(s).response, [0.5 + 0.25j])
    z = _write(tmp_path, "# GHz Z RI R (50+50j)\n1 0.5 0.25\n", "cz.s1p")
    with pytest.raises(DataError, match=r"line 1: reference resistance R \(50\+50j\) is not "
                       "a positive number of ohms"):
        fc.load(z)


def _s2p_rows(n, cut=None):
    rows = [f"{k + 1} 0.1 0 0.9 {k} 0.9 {k} 0.2 0" for k in range(n)]
    if cut is not None:
        rows[cut] = rows[cut].rsplit(" ", 2)[0]                 # 7 numbers, not 9
    return "# GHz S RI R 50\n" + "\n".join(rows) + "\n"


def test_short_or_long_record_names_its_line(tmp_path):
    with pytest.raises(DataError, match=r"line 5: 7 numbers, but a 2-port record needs 9 "
                       r"\(1 frequency \+ 4 pairs\), and line 6 starts the next record"):
        fc.load(_write(tmp_path, _s2p_rows(8, cut=3), "cut.s2p"), parameter="S21")
    # rows 2 (a pair short) and 3 (a pair long) of a 3-port: 38 numbers, two records'
    # worth, which a stream read would have taken silently shifted
    text = ("# GHz S RI R 50\n1 1 0 2 0 3 0\n4 0 5 0\n7 0 8 0 9 0\n"
            "2 1 0 2 0 3 0\n4 0 5 0 6 0\n7 0 8 0 9 0 9 9\n")
    with pytest.raises(DataError, match=r"line 4: the record that starts on line 2 ends here "
                       r"with 17 numbers \(line 4 holds 6\), but a 3-port record needs 19 "
                       r"\(1 frequency \+ 9 pairs\), and line 5 starts the next record"):
        fc.load(_write(tmp_path, text, "shift.s3p"), parameter="S21")
    long = "# GHz S RI R 50\n1 1 0 2 0 3 0\n4 0 5 0 6 0\n7 0 8 0 9 0 9 9\n"
    with pytest.raises(DataError, match=r"line 4: 8 numbers after 13 on lines 2-3 run past "
                       r"the record's end"):
        fc.load(_write(tmp_path, long, "long.s3p"), parameter="S21")
    with pytest.raises(DataError, match=r"line 3: 5 numbers run past the record's end: a "
                       r"1-port record needs 3 \(1 frequency \+ 1 pair\)"):
        fc.load(_write(tmp_path, "# GHz S RI R 50\n1 1 0\n2 1 0 3 0\n", "two.s1p"))


def test_wrapped_rows_still_read(tmp_path):
    # 5 ports: each matrix row wrapped after 4 pairs (frequency + 4 pairs, then 1 pair)
    lines = ["# GHz S RI R 50"]
    for f in (1, 2):
        for i in range(5):
            pairs = [f"{10 * i + j + f} 0" for j in range(5)]
            lines += [(f"{f} " if i == 0 else "") + " ".join(pairs[:4]), pairs[4]]
    data = _quiet_load(_write(tmp_path, "\n".join(lines) + "\n", "w.s5p"), parameter="S4,5")
    np.testing.assert_array_equal(data.response, [35.0, 36.0])


def test_version_2_short_line_is_named(tmp_path):
    text = ("[Version] 2.0\n# GHz S RI R 50\n[Number of Ports] 2\n[Network Data]\n"
            "1 1 0 2 0 3 0 4 0\n2 1 0 2 0 3 0\n3 1 0 2 0 3 0 4 0\n")
    with pytest.raises(DataError, match=r"line 6: 7 numbers, but a 2-port record needs 9"):
        fc.load(_write(tmp_path, text, "short.ts"), parameter="S21")


def test_version_2_rows_without_network_data_keyword(tmp_path):
    text = ("[Version] 2.0\n# MHz Z MA\n[Number of Ports] 1\n[Number of Frequencies] 2\n"
            "1 11 10\n2 12 20\n")
    with pytest.warns(DataWarning, match=r"2 numeric rows after the keywords \(lines 5-6\) "
                      r"but no \[Network Data\] keyword: read them as the network data"):
        data = fc.load(_write(tmp_path, text, "nokw.ts"))
    np.testing.assert_allclose(data.response, [11 * np.exp(1j * np.deg2rad(10)),
                                                12 * np.exp(1j * np.deg2rad(20))], rtol=1e-15)
    ref = text.replace("[Number of Frequencies] 2\n", "[Reference]\n50\n")
    with pytest.raises(DataError, match=r"3 numeric rows after the keywords \(lines 5-7\) but "
                       r"no \[Network Data\] keyword; write \[Network Data\]"):
        fc.load(_write(tmp_path, ref, "ref.ts"))


def test_rows_out_of_order_name_lines_in_the_file_unit(tmp_path):
    text = "# MHz S RI R 50\n140 1 0\n140.3 1 0\n140.9 1 0\n140.6 1 0\n"
    with pytest.raises(DataError, match=r"line 5: frequency 140.6 MHz follows 140.9 MHz on "
                       r"line 4; frequencies must increase: sort the rows by frequency"):
        fc.load(_write(tmp_path, text, "unordered.s1p"))
    text = "# MHz S RI R 50\n0 1 0\n140 1 0\n140.3 1 0\n140.3 2 0\n"
    with pytest.raises(DataError, match=r"line 5: frequency 140.3 MHz repeats the one on "
                       r"line 4; .*remove one of the two rows"):
        with pytest.warns(DataWarning, match="zero frequency"):
            fc.load(_write(tmp_path, text, "twice.s1p"))

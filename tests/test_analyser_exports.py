"""Published analyser exports, each written by the test byte for byte in its instrument's
layout: a Siglent oscilloscope's Bode export of two complete channels, a VNA script's
``Freq,S11dB,S11deg,...`` sweeps in repeated blocks, German and Spanish headers, a
headerless four-column file, Digilent WaveForms' impedance export (``Trace th (*)``,
``Trace |Z| (Ohm)``) and the HP/Agilent 4294A's ASCII export of two trace blocks.
"""

import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import DataError
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

def test_siglent_channels_are_recognised_each():
    # no space between the name and its unit: "CH1 Amplitude(dB)"
    assert [(c.role, c.unit) for c in map(recognise, (
        "Frequency(Hz)", "CH1 Amplitude(dB)", "CH1 Phase(Deg)", "CH2 Amplitude(dB)",
        "CH2 Phase(Deg)"))] == [("freq", "hz"), ("mag", "db"), ("phase", "deg"),
                                ("mag", "db"), ("phase", "deg")]


# --------------------------------------------------------------------------- VNA blocks

@pytest.mark.parametrize("name, role, unit", [
    ("S21dB", "mag", "db"), ("S21deg", "phase", "deg"), ("S21re", "re", None),
    ("S21im", "im", None), ("S21mag", "mag", "lin"), ("S21_dB", "mag", "db"),
    ("S21 deg", "phase", "deg"), ("S21_re", "re", None), ("S21 im", "im", None),
    ("S12rad", "phase", "rad")])
def test_an_sparameter_glued_to_its_format_is_that_parameter_s_column(name, role, unit):
    col = recognise(name)
    assert (col.role, col.unit) == (role, unit)
    assert sparameter_of(name) == name[:3].lower()


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

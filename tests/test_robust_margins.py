"""The margins of scripts/robust_design.py's report on loops with one and with several
gain crossovers (a crossing of |L| = 1 near +1 is far from -1: no negative margin)."""

import importlib.util
import math
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _load():
    spec = importlib.util.spec_from_file_location("robust_design_script",
                                                  ROOT / "scripts" / "robust_design.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


RD = _load()
W = np.geomspace(0.01, 1000.0, 20001)


def test_one_crossover_margins():
    """L = 1/(s (s + 1)): crossover 0.786 rad/s, PM 51.8 deg, delay margin 1.15 s."""
    s = 1j * W
    m = RD.margins(W, 1.0 / (s * (s + 1.0)))
    wc = math.sqrt((math.sqrt(5.0) - 1.0) / 2.0)
    pm = 180.0 - 90.0 - math.degrees(math.atan(wc))
    assert abs(m["omega_crossover"] - wc) < 1e-3
    assert abs(m["phase_margin_deg"] - pm) < 0.05
    assert abs(m["delay_margin"] - math.radians(pm) / wc) < 1e-3


def test_crossover_near_plus_one_is_not_a_negative_margin():
    """L = 1/(s (s + 1)) with a narrow magnitude peak at 50 rad/s that lifts |L| above 1
    where an extra lag of 172 deg puts L near +1 (phase about -351 deg): the signed
    180 + phase would read about -171 deg there. The phase margin is the first
    crossover's (51.8 deg, 0.786 rad/s); the delay margin is the smallest lag to -1 over
    the crossovers, over the crossover's frequency (the peak's: about 189 deg at 50
    rad/s, 66 ms, against 1.15 s at the first crossover)."""
    s = 1j * W
    x = np.log(W / 50.0)
    mag = np.abs(1.0 / (s * (s + 1.0))) * (1.0 + 5000.0 * np.exp(-(x / 0.05) ** 2))
    phase = (np.unwrap(np.angle(1.0 / (s * (s + 1.0))))
             - math.radians(172.0) * np.exp(-(x / 0.3) ** 2))
    loop = mag * np.exp(1j * phase)
    cross = np.flatnonzero(np.diff(np.sign(np.log(mag))) != 0)
    assert cross.size == 3                                 # 0.786 rad/s, the peak's edges
    m = RD.margins(W, loop)
    wc = math.sqrt((math.sqrt(5.0) - 1.0) / 2.0)
    pm = 180.0 - 90.0 - math.degrees(math.atan(wc))
    assert abs(m["phase_margin_deg"] - pm) < 0.05
    assert abs(m["omega_crossover"] - wc) < 1e-3
    lags = ((phase[cross[1:]] + math.pi) % (2 * math.pi)) / W[cross[1:]]
    assert np.all(np.degrees((phase[cross[1:]] + math.pi) % (2 * math.pi)) > 185.0)
    assert abs(m["delay_margin"] - lags.min()) <= 0.01 * lags.min()
    assert m["delay_margin"] < 0.1 * math.radians(pm) / wc

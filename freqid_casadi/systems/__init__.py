"""Benchmark systems of SPEC §4 as frequency-response data (layer L1).

Each benchmark has a low-level evaluator at complex ``s`` (``G_A_at``, ``G_B_at``, ...;
numpy complex in, complex out, same shape) and a function returning
:class:`~freqid_casadi.core.data.FrequencyData` on a frequency grid (``G_A``, ``G_B``, ...).
Without ``omega`` the grid is the thesis's: 500 log-spaced points from 1e-2 to 1e3 rad/s
(:func:`thesis_grid`).

The beam transfer functions are evaluated stably over the whole frequency range:

- near ``s = 0`` the hyperbolic/trigonometric combinations cancel to leading order, so a
  power series in ``z = m**4`` (the functions are even in the branch of the fourth root, hence
  analytic in ``z``) replaces the closed form for ``|z| < SERIES_THRESHOLD``;
- at high frequency ``cosh m``, ``cos m`` grow like ``exp(|Re m| + |Im m|)``; numerator and
  denominator are divided by that growth before the ratio is formed, so no overflow or
  precision loss occurs (tested up to ``omega = 1e5`` rad/s and beyond).

References: O. Demir, MSc thesis, Bilkent 2014, ch. 4 (examples A, B, C, §4.2 fractional);
S. O. R. Moheimani, ASME JDSMC 122 (2000), §3 (simply-supported beam, eq. 11).

The systems live in private modules (``_beams``: A, B, C and the perturbed plants;
``_fractional``: 1/sqrt(s), G_D and Moheimani's beam; ``_common``: the grid); every public
name is re-exported here (and :mod:`~freqid_casadi.systems.corpus`, the seeded corpus of
synthetic FRFs of issue 26: ``corpus(n, seed)``; ``_measured``: the measured FRFs shipped in
``freqid_casadi/datasets``, ``measured_sets()`` and ``measured(name)``), so
``freqid_casadi.systems.G_A()`` is the way to call them.
"""

from ._beams import (G_A, G_A_at, G_B, G_B_at, G_C, G_C_at, SERIES_THRESHOLD,
                     perturbed)
from ._common import thesis_grid
from .corpus import CorpusCase, CorpusSystem, FAMILIES, case, corpus
from ._measured import (MEASURED_SETS, MeasuredSet, measured, measured_file,
                        measured_sets, measured_source)
from ._fractional import (G_D, G_D_at, moheimani_at, moheimani_beam, moheimani_kopt,
                          moheimani_modes, sqrt_inverse, sqrt_inverse_at)


__all__ = [
    "thesis_grid",
    "G_A", "G_A_at",
    "G_B", "G_B_at",
    "G_C", "G_C_at",
    "sqrt_inverse", "sqrt_inverse_at",
    "G_D", "G_D_at",
    "perturbed",
    "moheimani_beam", "moheimani_at", "moheimani_modes", "moheimani_kopt",
    "SERIES_THRESHOLD",
    "corpus", "case", "CorpusCase", "CorpusSystem", "FAMILIES",
    "measured_sets", "measured", "measured_file", "measured_source", "MeasuredSet",
    "MEASURED_SETS",
]

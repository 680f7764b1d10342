"""The catalogue of built-in examples: system, model structure and the thesis's numbers (layer L1).

One entry per example of the thesis's chapter 4 (SPEC §4-§5): the benchmark system of
:mod:`freqid_casadi.systems`, the model structure the thesis fits to it (sections,
integrator, delay, basis) and the numbers it publishes in Table 4.1. The ``freqid example``
command, the thesis reproduction, the ablation and the published-numbers tests all read it.

Example::

    from freqid_casadi.systems.examples import EXAMPLES
    ex = EXAMPLES["A"]
    result = fc.fit(ex.data(), **ex.structure())
    result.max_rel_error <= ex.thesis.max_rel_error
"""

from dataclasses import dataclass
from typing import Callable, Optional

from .. import systems

__all__ = ["Example", "ThesisNumbers", "EXAMPLES", "TABLE_4_1", "FRACTIONAL_SECTIONS"]

#: Number of first-order sections for the 1/sqrt(s) example. The thesis (§4.2, figs
#: 4.20-4.21) does not state the order of its 1/sqrt(s) model in the text; 10 is our choice:
#: one real pole/zero pair per decade of the 1e-5..1e5 rad/s grid.
FRACTIONAL_SECTIONS = 10


@dataclass(frozen=True)
class ThesisNumbers:
    """The thesis's Table 4.1 row of one example (SPEC §5).

    Attributes
    ----------
    order : int
        Order of P_N (2 per second-order section).
    max_rel_error : float
        Max relative error ``max |(G - G_N)/G_N|`` of its NLLS method over the 500 points.
    subspace_max_rel_error : float
        The same for its subspace method.
    delay : float
        Its delay estimate h (s).
    """

    order: int
    max_rel_error: float
    subspace_max_rel_error: float
    delay: float

    def as_dict(self):
        """``{"order", "max_rel_error", "delay", "source": "thesis"}``: the published numbers
        a fit report compares with (:func:`freqid_casadi.report.folder.fit_summary`)."""
        return dict(order=self.order, max_rel_error=self.max_rel_error, delay=self.delay,
                    source="thesis")


@dataclass(frozen=True)
class Example:
    """A built-in example: its system and the structure the thesis fits to it.

    Attributes
    ----------
    name : str
        ``"A"``, ``"B"``, ``"C"`` or ``"fractional"``.
    system : callable
        ``system(omega=None) -> FrequencyData`` (default grid: the thesis's 500 points).
    n_sections : int
        Sections of the model at the thesis's order.
    integrator, delay : bool
        Whether the model has the factor 1/s and a fitted delay.
    basis : str
        ``"second-order"`` or ``"first-order"`` sections.
    true_delay : float or None
        The delay of the true system (s); None where G has none.
    thesis : ThesisNumbers or None
        Table 4.1 of the thesis (None for the fractional example).
    """

    name: str
    system: Callable
    n_sections: int
    integrator: bool
    delay: bool
    basis: str
    true_delay: Optional[float]
    thesis: Optional[ThesisNumbers]

    def data(self, omega=None):
        """The example's data: ``system(omega)`` (omega in rad/s; None: the default grid)."""
        return self.system() if omega is None else self.system(omega)

    def truth(self, omega):
        """The true response at ``omega`` (rad/s): complex ndarray, shape (M,)."""
        return self.system(omega).response

    def structure(self, n_sections=None):
        """Keyword arguments of :func:`freqid_casadi.fitting.fit.fit` for this example's model.

        Parameters
        ----------
        n_sections : int, optional
            Override the thesis's number of sections.

        Returns
        -------
        dict
            ``n_sections``, ``integrator``, ``delay``, ``basis``.
        """
        return dict(n_sections=int(n_sections or self.n_sections), integrator=self.integrator,
                    delay=self.delay, basis=self.basis)

    @property
    def order(self):
        """Order of P_N at ``n_sections`` (2 per second-order section, 1 per first-order)."""
        return (2 if self.basis == "second-order" else 1) * self.n_sections


#: Table 4.1 of the thesis (SPEC §5), by example.
TABLE_4_1 = {
    "A": ThesisNumbers(order=34, max_rel_error=0.2549, subspace_max_rel_error=2.5724,
                       delay=0.0106),
    "B": ThesisNumbers(order=18, max_rel_error=0.0027, subspace_max_rel_error=0.0044,
                       delay=0.011),
    "C": ThesisNumbers(order=54, max_rel_error=5.9884, subspace_max_rel_error=7.3382,
                       delay=0.0261),
}

#: The built-in examples at the thesis's orders (thesis §4.1-§4.2; SPEC §4-§5).
EXAMPLES = {
    "A": Example("A", systems.G_A, 17, True, True, "second-order", 0.01, TABLE_4_1["A"]),
    "B": Example("B", systems.G_B, 9, False, True, "second-order", None, TABLE_4_1["B"]),
    "C": Example("C", systems.G_C, 27, True, True, "second-order", 0.02625, TABLE_4_1["C"]),
    "fractional": Example("fractional", systems.sqrt_inverse, FRACTIONAL_SECTIONS, False,
                          False, "first-order", None, None),
}

"""The stabilization diagram of a modal survey (layer L6): estimate a range of orders with
one shared set of poles and mark every pole as new, stable in frequency, or stable in
frequency and damping against the previous order (SDynPy's tolerances 1 % and 10 % by
default); the modes that stay stable are selected.

As in modal practice (LSCF/PolyMAX), each order of the diagram is a cheap linear estimate
by default: the shared-pole vector fitting that starts
:func:`freqid_casadi.fit_shared`'s rational start (:mod:`freqid_casadi.modal._estimate`),
the orders in worker processes with ``n_jobs``; the selected modes are then polished by
one :func:`~freqid_casadi.fit_shared` with a shared section per pole stable in frequency
and damping at the highest order (``StabilizationResult.polished``).
``estimator="full"`` fits every order with :func:`~freqid_casadi.fit_shared` instead (the
survey before: on 16 channels x 1000 points over orders 2..40, 1180 s of CPU against 6.5 s,
the same ten modes within 2e-6 in frequency and 1e-4 in damping, relative).
"""

import csv
import inspect
import io
import numbers
import warnings
from dataclasses import dataclass

import numpy as np

from .._progress import channel, check_progress
from .._validate import check_choice, check_flag
from ..errors import OptionError
from ._estimate import OrderEstimate, estimate_order, run_orders

__all__ = ["StabilizationPole", "StabilizationOrder", "StabilizationResult", "OrderEstimate",
           "ESTIMATORS", "parse_orders", "stabilization", "stabilization_csv"]

#: The estimators of :func:`stabilization`: "rational" (the shared-pole vector fitting at
#: every order, then one polish of the selected modes) and "full" (fit_shared at every
#: order).
ESTIMATORS = ("rational", "full")


@dataclass(frozen=True)
class StabilizationPole:
    """A pole of one order.

    Attributes
    ----------
    order : int
        Number of poles of the fit.
    omega_n : float
        Natural frequency (rad/s).
    frequency_hz : float
        ``omega_n / (2 pi)``.
    zeta : float
        Damping ratio.
    status : str
        One of :data:`freqid_casadi.core.modes.STATUSES`.
    """

    order: int
    omega_n: float
    frequency_hz: float
    zeta: float
    status: str


@dataclass(frozen=True, eq=False)
class StabilizationOrder:
    """The progress record of one order of :func:`stabilization` (what a ``progress``
    callable receives).

    Attributes
    ----------
    order : int
        Model order (number of shared poles).
    fit : OrderEstimate or SharedFitResult
        The order's estimate (``estimator="rational"``) or fit (``"full"``).
    statuses : tuple of str
        Each mode's status against the order before ("new", "stable-frequency" or
        "stable-frequency-damping").
    """

    order: int
    fit: object
    statuses: tuple

    def line(self):
        """One line of text (``progress="lines"``)."""
        how = ("vector fitting" if isinstance(self.fit, OrderEstimate)
               else f"fit {self.fit.status}")
        return (f"order {self.order}: {len(self.statuses)} modes, "
                f"{self.statuses.count('stable-frequency-damping')} stable, {how}, max rel. "
                f"error {np.max(self.fit.max_rel_errors):.3g}")


@dataclass(frozen=True, eq=False)
class StabilizationResult:
    """Result of :func:`stabilization`.

    Attributes
    ----------
    orders : tuple of int
        Model orders (number of shared poles, 2 x sections).
    poles : tuple of StabilizationPole
        Every underdamped pole of every order.
    modes : tuple of Mode
        The automatically selected physical modes (see :func:`stabilization`): with
        ``estimator="rational"`` and ``polish``, the modes of :attr:`polished` matched to
        the selected poles of the highest order's estimate (a selected pole the polish has
        no pole for within ``freq_tol`` keeps its estimate, and the note says so); without
        ``polish`` the estimate's; with ``estimator="full"`` the highest order's fit's.
    fits : tuple of OrderEstimate or tuple of SharedFitResult
        One per order: with ``estimator="rational"`` each order's shared-pole vector
        fitting (:class:`OrderEstimate`: poles, modes and errors, no models); with
        ``"full"`` each order's :func:`~freqid_casadi.fit_shared` result.
    freq_tol, damping_tol : float
    omega : ndarray of float, shape (M,)
        rad/s.
    summed_magnitude : ndarray of float, shape (M,)
        ``sum_c |Phi_c|`` (the curve the diagram is drawn over).
    selection_note : str
        Why each pole of the highest order was not selected (or why none could be), empty
        when every one was.
    estimator : str
        "rational" or "full" (:data:`ESTIMATORS`).
    polished : SharedFitResult or None
        With ``estimator="rational"`` and ``polish``: the
        :func:`~freqid_casadi.fit_shared` fit (the survey's fit options) with a shared
        section per stable pole of the highest order (see :func:`stabilization`),
        whose models are the survey's model; None when nothing was selected, without
        ``polish``, or with ``estimator="full"``.
    selected_poles : tuple of StabilizationPole
        The poles of the highest order selected as modes (as the diagram shows them; with
        a polish, :attr:`modes` holds the polished values).
    """

    orders: tuple
    poles: tuple
    modes: tuple
    fits: tuple
    freq_tol: float
    damping_tol: float
    omega: np.ndarray
    summed_magnitude: np.ndarray
    selection_note: str = ""
    estimator: str = "full"
    polished: object = None
    selected_poles: tuple = ()

    def poles_of(self, order):
        """The StabilizationPoles of one order."""
        return tuple(p for p in self.poles if p.order == order)


def parse_orders(text):
    """``"2:40:2"`` (start:stop:step, stop included) or ``"4,8,12"`` -> tuple of even ints.

    Parameters
    ----------
    text : str
    """
    try:
        if ":" in str(text):
            parts = [int(t) for t in str(text).split(":")]
            start, stop = parts[0], parts[1]
            step = parts[2] if len(parts) > 2 else 2
            orders = tuple(range(start, stop + 1, step))
        else:
            orders = tuple(int(t) for t in str(text).split(","))
    except (ValueError, IndexError):
        raise OptionError(f"orders must look like 2:40:2 or 4,8,12, got {text!r}") from None
    return _check_orders(orders)


def _check_orders(orders):
    if isinstance(orders, str):
        orders = parse_orders(orders)
    try:
        given = tuple(orders)
    except TypeError:
        raise OptionError(f"orders must be a sequence of even integers or a string such as "
                          f"'2:40:2', got {orders!r}") from None
    if any(isinstance(o, (bool, np.bool_)) or not isinstance(o, (int, np.integer))
           for o in given):
        raise OptionError(f"orders must be integers, got {given!r:.80}")
    orders = tuple(int(o) for o in given)
    if not orders or any(o < 2 or o % 2 for o in orders) or list(orders) != sorted(set(orders)):
        raise OptionError(f"orders must be increasing even numbers >= 2 (the number of "
                          f"shared poles), got {orders}")
    return orders


def _check_tolerances(freq_tol, damping_tol, min_stable):
    """OptionError for tolerances that are not real numbers or a ``min_stable`` that is not
    an integer >= 1 (their ranges are checked by :func:`stabilization`)."""
    for name, value in (("freq_tol", freq_tol), ("damping_tol", damping_tol)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            raise OptionError(f"{name} must be a number, got {value!r}")
    if isinstance(min_stable, (bool, np.bool_)) or \
            not isinstance(min_stable, (int, np.integer)) or min_stable < 1:
        raise OptionError(f"min_stable must be an integer >= 1 (orders a mode must stay "
                          f"stable), got {min_stable!r}")


def _match(prev, cur, freq_tol, damping_tol):
    """Status of each (omega_n, zeta) of ``cur`` against the poles of ``prev`` and the index
    of its match in ``prev`` (or None). One-to-one: the closest pairs (relative frequency
    distance) are matched first, so a spurious pole beside a physical one stays "new"."""
    pairs = sorted((abs(pw - w) / w, i, j) for i, (w, _) in enumerate(cur)
                   for j, (pw, _) in enumerate(prev))
    match, used = [None] * len(cur), set()
    for dist, i, j in pairs:
        if dist <= freq_tol and match[i] is None and j not in used:
            match[i] = j
            used.add(j)
    status = []
    for i, (w, z) in enumerate(cur):
        if match[i] is None:
            status.append("new")
        elif abs(prev[match[i]][1] - z) <= damping_tol * max(z, 1e-12):
            status.append("stable-frequency-damping")
        else:
            status.append("stable-frequency")
    return status, match


def _classify(prev, cur, freq_tol, damping_tol):
    """Statuses of :func:`_match`."""
    return _match(prev, cur, freq_tol, damping_tol)[0]


def stabilization(datas, orders=tuple(range(2, 41, 2)), *, freq_tol=0.01, damping_tol=0.10,
                  min_stable=3, progress=False, estimator="rational", polish=True, n_jobs=1,
                  **fit_options):
    """Stabilization diagram: shared-pole estimates (or fits) of a range of orders.

    Parameters
    ----------
    datas : sequence of FrequencyData
        As :func:`~freqid_casadi.modal.shared.fit_shared`: one FRF per channel, one omega
        grid (rad/s).
    orders : sequence of int or str
        Even model orders (number of poles) ``2 n_sections``, increasing; or a string
        such as "2:40:2" (:func:`parse_orders`).
    freq_tol : float
        A pole is stable in frequency when a pole of the previous order lies within
        ``freq_tol`` (relative, default 1 %).
    damping_tol : float
        ... and stable in damping when that pole's damping ratio is within ``damping_tol``
        (relative, default 10 %).
    min_stable : int
        A pole of the highest order is selected as a physical mode when it and its
        predecessors were "stable-frequency-damping" over the last ``min_stable`` orders
        (each status compares an order with the one before, so at least
        ``min_stable + 1`` orders are needed: with fewer none is selected, and
        :attr:`StabilizationResult.selection_note` says why).
    progress : bool, "lines" or callable
        As for :func:`~freqid_casadi.modal.shared.fit_shared`, one record per order: True
        draws a bar on a terminal (elsewhere a line per 30 s of a long run), "lines" writes
        one line per order to stderr, a callable receives each :class:`StabilizationOrder`
        (with ``n_jobs > 1`` all of them once every order is done).
    estimator : {"rational", "full"}
        "rational" (default): each order is the shared-pole vector fitting that
        :func:`~freqid_casadi.fit_shared`'s rational start begins with
        (:class:`OrderEstimate`, numpy only: with the polish 6.5 s of CPU for 16 channels
        x 1000 points over orders 2..40, against 1180 s for "full"). "full": each order is
        a whole :func:`~freqid_casadi.fit_shared` (warm restarts, IPOPT), the survey as it
        was.
    polish : bool
        With ``estimator="rational"`` (default True): one
        :func:`~freqid_casadi.fit_shared` (``fit_options``) with a shared section per pole
        of the highest order that is "stable-frequency-damping" there (at least one per
        selected mode: a stable pole the selection did not keep, not yet stable over
        ``min_stable`` orders, keeps its section and does not bias the selected ones; with
        one section for one selected mode of two, measured, the damping moved 28 %. A pole
        stable in frequency only, typically a heavily damped computational pole whose
        damping wanders, gets none), :attr:`StabilizationResult.polished`; the reported
        modes are its modes matched to the selected poles. False: the estimate's modes,
        no model. No effect with "full".
    n_jobs : int
        Worker processes for the orders (forked on Linux, else joblib's loky backend; one
        BLAS thread each); 1 (default) runs them in this process. The result does not
        depend on it.
    **fit_options
        Keywords of :func:`~freqid_casadi.modal.shared.fit_shared` (integrator, delay,
        zeros, weights, channel_sections, balance_channels, method, vector_fitting, ...),
        checked before any order is run. The estimator uses ``weights``, ``integrator``
        (the data times ``j omega``), ``vector_fitting`` (its iterations) and
        ``channel_sections`` (no constant per channel with them, as fit_shared's start);
        the others shape the polish (or each fit with "full"): a delay in particular is
        left to the polish. With ``channel_sections``
        the order counts the shared poles only; each channel's own poles are not in the
        diagram.

    Returns
    -------
    StabilizationResult

    Raises
    ------
    DataError, OptionError
        Before any order is run: bad data, orders, tolerances or fit options, or a
        highest order with more parameters than the data have points.
    """
    from .shared import check_largest_order, fit_shared

    orders = _check_orders(orders)
    _check_tolerances(freq_tol, damping_tol, min_stable)
    check_choice("estimator", estimator, ESTIMATORS)
    polish = check_flag("polish", polish)
    _check_jobs(n_jobs)
    check_largest_order(datas, orders[-1] // 2, fit_options)     # before any fit is run
    if not (0 < freq_tol < 1 and 0 < damping_tol < 10):
        raise OptionError(f"freq_tol must be in (0, 1) and damping_tol in (0, 10), got "
                          f"{freq_tol}, {damping_tol}")
    progress = check_progress(progress, "each StabilizationOrder")
    checked = _estimator_inputs(datas, orders[-1] // 2, fit_options)
    if estimator == "rational":
        task, args = estimate_order, [checked[1:4] + (o // 2,) + checked[4:] for o in orders]
    else:
        task, args = _fit_order, [(checked[0], o // 2, fit_options) for o in orders]
    fits, poles, prev, history = [], [], [], []
    with channel(progress, StabilizationOrder.line, total=len(orders), unit="order") as emit:
        for order, res in zip(orders, run_orders(task, args, n_jobs)):
            fits.append(res)
            cur = [(m.omega_n, m.zeta) for m in res.modes]
            status, match = _match(prev, cur, freq_tol, damping_tol)
            history.append((status, match))
            poles += [StabilizationPole(order, w, w / (2 * np.pi), z, s)
                      for (w, z), s in zip(cur, status)]
            emit(StabilizationOrder(order, res, tuple(status)))
            prev = cur
    selected, note = _select(fits[-1].modes, history, min_stable, orders, fits)
    top = poles[len(poles) - len(fits[-1].modes):]
    chosen = tuple(p for p, m in zip(top, fits[-1].modes) if any(m is k for k in selected))
    polished = None
    if estimator == "rational" and polish and selected:
        n_polish = max(len(selected),
                       history[-1][0].count("stable-frequency-damping"))
        polished = fit_shared(checked[0], n_polish, **fit_options)
        selected, missed = _polished_modes(selected, polished, freq_tol)
        note = "; ".join(t for t in (note, missed) if t)
    return StabilizationResult(
        orders=orders, poles=tuple(poles), modes=selected, fits=tuple(fits),
        freq_tol=float(freq_tol), damping_tol=float(damping_tol), omega=checked[1],
        summed_magnitude=np.sum([np.abs(d.response) for d in checked[0]], axis=0),
        selection_note=note, estimator=estimator, polished=polished, selected_poles=chosen)


def _check_jobs(n_jobs):
    if isinstance(n_jobs, (bool, np.bool_)) or not isinstance(n_jobs, (int, np.integer)) \
            or n_jobs < 1:
        raise OptionError(f"n_jobs must be a positive integer (worker processes), got "
                          f"{n_jobs!r}; pass n_jobs=2 to run the orders in two processes")


def _fit_order(datas, n_sections, options):
    """One order of ``estimator="full"`` (a module-level function: worker processes)."""
    from .shared import fit_shared

    return fit_shared(datas, n_sections, **options)


def _estimator_inputs(datas, n_sections, options):
    """``(datas, omega, phi, wts, n_iter, constant, integrator)`` of the estimator, from
    fit_shared's own checks of ``options`` (OptionError for an unknown keyword or a bad
    value, before any order is run): ``phi`` the rational part (times ``j omega`` with an
    integrator), ``wts`` fit_shared's normalised weights, ``constant`` unless the channels
    have sections of their own (fit_shared's rational start)."""
    from .shared import (_check_datas, _check_numbers, _check_options, _solver_options,
                         fit_shared)

    params = inspect.signature(fit_shared).parameters
    known = sorted(set(params) - {"datas", "n_sections", "progress"})
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise OptionError(f"unknown fit option(s) {', '.join(map(repr, unknown))}: "
                          f"stabilization passes its other keywords to fit_shared, which "
                          f"takes {', '.join(known)}")

    def get(name):
        return options.get(name, params[name].default)

    datas, omega, phi, wts = _check_datas(datas, get("weights"))
    _check_options(n_sections, get("delay"), get("zeros"), get("start"), len(datas),
                   get("channel_sections"))
    _check_numbers(get("integrator"), get("delay_max"), get("balance_channels"))
    with warnings.catch_warnings():     # the renamed keywords warn in fit_shared itself
        warnings.simplefilter("ignore", FutureWarning)
        vf = _solver_options(get("method"), get("vector_fitting"), get("max_iter"),
                             get("n_vf_iter"))[1]
    integrator = bool(get("integrator"))
    base = phi * (1j * omega) if integrator else phi
    return (tuple(datas), omega, base, wts, vf.n_iter, not get("channel_sections"),
            integrator)


def _polished_modes(selected, polished, freq_tol):
    """The modes of the ``polished`` fit matched one-to-one (closest first, within
    ``freq_tol``) to the ``selected`` estimates, an unmatched estimate kept as it is; and a
    note naming the unmatched ones (empty when none)."""
    _, match = _match([(m.omega_n, m.zeta) for m in polished.modes],
                      [(m.omega_n, m.zeta) for m in selected], freq_tol, 1.0)
    keep = [polished.modes[j] if j is not None else m for m, j in zip(selected, match)]
    missed = [f"{m.frequency_hz:.6g} Hz" for m, j in zip(selected, match) if j is None]
    note = (f"the polished fit ({polished.n_shared} shared sections) has no pole within the "
            f"frequency tolerance of {', '.join(missed)}: kept as estimated (see "
            "StabilizationResult.polished)" if missed else "")
    return tuple(sorted(keep, key=lambda m: m.omega_n)), note


def _select(last, history, min_stable, orders, fits):
    """Modes of the highest order whose chain of matched predecessors was "stable-frequency-
    damping" at each of the last ``min_stable`` orders, and a note saying why the others
    were not selected.

    A status compares an order with the one before, so ``min_stable`` stable orders need
    ``min_stable + 1`` orders: with fewer, nothing is selected (the note says so)."""
    k = int(min_stable)
    if len(history) < k + 1:
        return (), (f"no mode can be selected: a mode must be stable in frequency and "
                    f"damping at {k} successive orders (min_stable={k}), each against the "
                    f"order before, which needs at least {k + 1} orders; {len(orders)} "
                    f"given ({', '.join(map(str, orders))}); add orders or lower min_stable")
    keep, why = [], []
    for i, mode in enumerate(last):
        idx, reason = i, None
        for j, (status, match) in enumerate(history[::-1][:k]):
            if status[idx] != "stable-frequency-damping":
                reason = _break_reason(status[idx], orders, len(history) - 1 - j, match[idx],
                                       fits, idx)
                break
            idx = match[idx]
        if reason is None:
            keep.append(mode)
        else:
            why.append(f"{mode.frequency_hz:.6g} Hz (zeta {mode.zeta:.3g}): {reason}")
    unconverged = [o for o, f in zip(orders[-k - 1:], fits[-k - 1:]) if not f.success]
    note = "; ".join(why)
    if why and unconverged:
        note += (f"; orders {unconverged} did not converge (their poles may be off): pass "
                 "method=IpoptOptions(final_max_iter=4000), or see each order's message")
    return tuple(keep), note


def _break_reason(status, orders, pos, j, fits, idx):
    """Why the chain of a top-order pole broke at ``orders[pos]`` (its pole ``idx`` there,
    matched to pole ``j`` of the order before, or None)."""
    order, prev = orders[pos], orders[pos - 1]
    if status == "new":
        return (f"at order {order} no pole of order {prev} lies within the frequency "
                "tolerance")
    cur = fits[pos].modes[idx].zeta
    old = fits[pos - 1].modes[j].zeta
    return (f"at order {order} its damping {cur:.3g} differs from order {prev}'s {old:.3g} "
            f"by {abs(cur - old) / max(cur, 1e-12):.0%} (more than the damping tolerance)")


def stabilization_csv(result):
    """CSV text: order, frequency_hz, omega_n, zeta, status, selected (one row per pole).

    Parameters
    ----------
    result : StabilizationResult
    """
    chosen = {id(p) for p in result.selected_poles}
    if not chosen:                                  # a result built without them
        chosen = {id(p) for p in result.poles_of(result.orders[-1])
                  if p.omega_n in {m.omega_n for m in result.modes}}
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["order", "frequency_hz", "omega_n_rad_s", "zeta", "status", "selected"])
    for p in result.poles:
        w.writerow([p.order, repr(p.frequency_hz), repr(p.omega_n), repr(p.zeta), p.status,
                    int(id(p) in chosen)])
    return buf.getvalue()

"""Fit every order of a range and find the smallest that meets a target (layer L4).

:func:`sweep` runs :func:`freqid_casadi.fitting.fit.fit` once per order and tabulates the max and
RMS relative error, the delay and the time; with a ``truth`` callable (an analytic system)
it also gives the max relative error on a denser grid than the fitted one, the honest
error between the samples.

Nested model classes never lose: when an order follows the previous one by one section,
the previous model with one more section at its largest error (an identity section there,
so the start has exactly the previous error) is polished on all data as a second start, and
the better of the two models is kept, so N+1 sections are never worse than N.
"""

import numbers
import time

from dataclasses import dataclass

import numpy as np

from ._checks import validate, without_phase_check
from .._progress import channel, check_progress
from .._threads import single_threaded_blas
from ..core.data import FrequencyData, dense_grid
from ..errors import DataError, OptionError
from .fit import fit
from .verdict import FitStatus, residual_noise, status_of
from ..core.metrics import relative_error
from ..core.model import RationalDelayModel

__all__ = ["SweepRow", "SweepResult", "sweep", "parse_orders", "MAX_ORDERS",
           "EXTEND_MAX_ITER"]

#: Iteration limit of the polish of the extended start (the previous order's model with one
#: more section) when :func:`fit` also runs at that order (``incremental=False``).
EXTEND_MAX_ITER = 50


@dataclass(frozen=True)
class SweepRow:
    """One order of a sweep.

    Attributes
    ----------
    order : int
        Order of P_N (2N for second-order sections, N for first-order).
    n_sections : int
    max_rel_error, rms_rel_error : float
        Over the data points.
    max_rel_error_dense : float
        Over a grid ``dense_factor`` times denser (nan without ``truth``).
    delay : float
        Seconds.
    wall_time : float
        Seconds.
    success : bool
    start : str
        Which start gave the kept model: the fit's (``FitResult.start``) or "extended"
        (the previous order's model with one more section, polished).
    status : FitStatus
        What the kept model means, as ``FitResult.status``: "ok" (converged, its residual
        consistent with the noise), "poor-fit" (converged, residual well above the noise:
        more sections, or another model class) or "not-converged".
    """

    order: int
    n_sections: int
    max_rel_error: float
    rms_rel_error: float
    max_rel_error_dense: float
    delay: float
    wall_time: float
    success: bool
    start: str
    status: FitStatus = None


@dataclass(frozen=True)
class SweepResult:
    """All orders of a sweep.

    Attributes
    ----------
    rows : tuple of SweepRow
    target : float or None
        The max relative error aimed at.
    best_order : int or None
        The smallest order meeting ``target``.
    data_name : str
    """

    rows: tuple
    target: float
    best_order: int
    data_name: str

    def as_dict(self):
        return {"data": self.data_name, "target": self.target, "best_order": self.best_order,
                "rows": [dict(r.__dict__) for r in self.rows]}


#: Most orders one sweep fits (each is a whole fit).
MAX_ORDERS = 200


def _count(n):
    if n > MAX_ORDERS:
        raise OptionError(f"{n} orders to fit, more than {MAX_ORDERS} in one sweep; use a "
                          "larger step or a shorter range (e.g. --orders 2:40:2)")


def parse_orders(spec):
    """Parse "4:40:2" (start:stop:step, stop included), "4,8,12" or "10" into a list.

    Numbers are plain ASCII decimal integers (no "1_0", no non-ASCII digits); at most
    :data:`MAX_ORDERS` orders, counted before the list is built.

    Parameters
    ----------
    spec : str

    Returns
    -------
    list of int

    Raises
    ------
    OptionError
        A malformed ``spec``, or more than :data:`MAX_ORDERS` orders.
    """
    def number(p):
        p = p.strip()
        if not (p.isascii() and p.isdigit()) or len(p) > 12:
            raise ValueError
        return int(p)

    try:
        if not isinstance(spec, str) or len(spec) > 10_000:
            raise ValueError
        if ":" in spec:
            parts = [number(p) for p in spec.split(":")]
            if len(parts) == 2:
                parts.append(1)
            start, stop, step = parts
            if step <= 0 or start <= 0 or stop < start:
                raise ValueError
            _count((stop - start) // step + 1)
            return list(range(start, stop + 1, step))
        orders = [number(p) for p in spec.split(",")]
        if any(o <= 0 for o in orders):
            raise ValueError
        _count(len(orders))
        return orders
    except OptionError:
        raise
    except ValueError:
        raise OptionError(f"bad orders {spec!r:.80}: use start:stop:step with positive "
                          "integers (e.g. 4:40:2), or a comma-separated list") from None


def sweep(data, orders, *, target=None, truth=None, dense_factor=10, progress=False,
          incremental=True, **fit_options):
    """Fit ``data`` at each order in ``orders``.

    Parameters
    ----------
    data : FrequencyData
    orders : iterable of int
        Orders of P_N; with the second-order basis each must be even (N = order/2).
    target : float, optional
        Max relative error to meet; ``best_order`` is the smallest order meeting it.
    truth : callable, optional
        ``omega (rad/s) -> complex response`` of the true system, to evaluate the error on
        a log grid ``dense_factor`` times denser than the data.
    dense_factor : int
        Points of the dense grid per data point (:func:`~freqid_casadi.core.data.dense_grid`).
    progress : bool, "lines" or callable, optional
        True draws a bar on a terminal (elsewhere a line per 30 s of a long run), "lines"
        writes a line per order to stderr, a callable receives each :class:`SweepRow` as it
        is done.
    incremental : bool
        With the sequential start (the default), an order one section above the previous
        is fitted only from the previous order's model with one more section at its
        largest error, polished on all data (the sequential loop continued: about one
        stage per order instead of a whole fit), unless the previous model is no better
        than an infinite gain (max relative error >= 1); False (or another ``start``) also
        runs :func:`~freqid_casadi.fitting.fit.fit` at every order and keeps the better model.
        Either way the max error never increases with the order.
    **fit_options
        Passed to :func:`~freqid_casadi.fitting.fit.fit` (``integrator``, ``start``, ...);
        ``start`` defaults to "sequential" here, unlike :func:`fit` (the sweep continues
        the sequential loop from order to order; ``freqid sweep`` passes "best").

    Returns
    -------
    SweepResult
    """
    if not isinstance(data, FrequencyData):
        raise OptionError("sweep takes a FrequencyData")
    fit_options = {"start": "sequential", **fit_options}
    if target is not None and (isinstance(target, (bool, np.bool_))
                               or not isinstance(target, numbers.Real)
                               or not (np.isfinite(target) and target > 0)):
        raise OptionError(f"target must be a number > 0, got {target!r}")
    progress = check_progress(progress, "each SweepRow")
    basis = fit_options.get("basis", "second-order")
    per = 2 if basis == "second-order" else 1
    orders = _orders(orders)
    if orders:                  # the largest order fits the data, before any fit is run
        validate(data, None, max(orders) // per, basis, None,
                 _integrator_check(fit_options.get("integrator", False)),
                 fit_options.get("weights"))
    for o in orders:
        if o % per:
            raise OptionError(f"order {o} is odd: second-order sections give even orders; "
                              "use even orders or basis='first-order'")
    dense = None
    if truth is not None:
        dense = dense_grid(data.omega, dense_factor)
        g_dense = _truth_values(truth, dense)
    rows = []
    chain = shown = None        # the continued model, and the last row's (model, max, rms, ok)
    only_ext = incremental and fit_options.get("start", "sequential") == "sequential"
    # one BLAS thread, as fit() has: the relocated starts' least-squares problems are
    # small, and OpenBLAS threads on a busy 2-core machine made each scipy lstsq of
    # example A (1000 x 160) take 1.8 s instead of 8 ms (the whole sweep 94 s, not 2)
    # a row keeps a fit's model, errors, success and status, not its diagnostics: the fits
    # skip the non-minimum-phase check (half the time of example A's sweep)
    with single_threaded_blas(), without_phase_check(), \
            channel(progress, _row_line, total=len(orders), unit="order") as emit:
        for o in orders:
            t0 = time.perf_counter()
            follows = chain is not None and chain[0].n_sections + 1 == o // per
            cand = []
            # a previous model no better than an infinite gain (max error >= 1) is a poor start
            if not (follows and only_ext and chain[3] < 1.0):
                res = fit(data, n_sections=o // per, **fit_options)
                cand.append((res.model, res.max_rel_error, res.rms_rel_error, res.success,
                             res.start, res.status))
            else:
                res = chain[1]
            if follows:
                cand.append(_extended(chain[0], res, data,
                                      None if only_ext else EXTEND_MAX_ITER)
                            + ("extended", None))
            best = cand[0]
            for c in cand[1:]:
                best = c if _better(c[1:3], best[1:3]) else best
            # the sequential loop continues from its best model; the row never gets worse
            chain = (best[0], res, best[3], best[1])
            if follows and shown is not None and shown[0].n_sections + 1 == o // per:
                same = _identity_extension(shown[0], data) + (shown[3], "extended", None)
                # the same model plus an identity section: the max error never increases
                best = same if same[1] < best[1] or _better(same[1:3], best[1:3]) else best
            model, mx, rms, success, start, status = best
            if status is None:          # an extended model: its status from its residual
                status = _status(model, data, success, rms)
            shown = best
            dense_err = (relative_error(model, dense, g_dense).max
                         if dense is not None else float("nan"))
            row = SweepRow(order=o, n_sections=o // per, max_rel_error=mx, rms_rel_error=rms,
                           max_rel_error_dense=dense_err, delay=model.delay,
                           wall_time=time.perf_counter() - t0, success=success, start=start,
                           status=status)
            rows.append(row)
            emit(row)
    meeting = [r.order for r in rows if target is not None and r.max_rel_error <= target]
    return SweepResult(rows=tuple(rows), target=target,
                       best_order=min(meeting) if meeting else None, data_name=data.name)


def _status(model, data, success, rms):
    """The :class:`FitStatus` of ``model`` on ``data`` (``success``: its polish converged),
    from its residual as :func:`~freqid_casadi.fitting.fit.fit` decides a fit's."""
    with np.errstate(all="ignore"):
        residual = data.response / model.frequency_response(data.omega) - 1.0
    return status_of(bool(success), not rms < 1.0,
                     residual_noise(residual, data.omega, data.weights))


def _row_line(row):
    """One line of text for a sweep row (``progress="lines"`` and the bar's summary)."""
    return (f"order {row.order}: {row.status}, max rel. error {row.max_rel_error:.3e}, "
            f"delay {row.delay:.6g}, {row.wall_time:.1f} s")


def _integrator_check(integrator):
    """The integrator option as validate checks it ("auto" has the shape of False)."""
    return False if isinstance(integrator, str) and integrator == "auto" else integrator


def _orders(orders):
    """The list of int orders of :func:`sweep` (a string is parsed by :func:`parse_orders`);
    OptionError for anything but integers."""
    if isinstance(orders, str):
        return parse_orders(orders)
    if hasattr(orders, "__len__"):
        _count(len(orders))                 # before a range is turned into a list
    try:
        out = list(orders)
    except TypeError:
        raise OptionError(f"orders must be a list of even integers or a string such as "
                          f"'4:40:2', got {orders!r}") from None
    _count(len(out))
    for o in out:
        if isinstance(o, (bool, np.bool_)) or not isinstance(o, numbers.Integral):
            raise OptionError(f"orders must be integers, got {o!r} in {orders!r:.80}")
    return [int(o) for o in out]


def _truth_values(truth, dense):
    """``truth(dense)``, checked: one finite, nonzero complex value per frequency."""
    try:
        values = np.asarray(truth(dense), complex)
    except (TypeError, ValueError) as exc:
        raise DataError(f"truth(omega) must return complex values: {exc}") from None
    if values.shape != dense.shape or not np.all(np.isfinite(values)) or np.any(values == 0):
        raise DataError(f"truth(omega) must return one finite, nonzero complex value per "
                        f"frequency: shape {dense.shape} expected, got {values.shape}"
                        + ("" if values.shape != dense.shape else
                           ", with values not finite or zero")
                        + "; pass a callable such as model.frequency_response")
    return values


def _better(a, b):
    """``(max, rms)`` a better than b: a lower max error (within 0.1 %, a lower RMS)."""
    if a[0] < b[0] * 0.999:
        return True
    return a[0] <= b[0] * 1.001 and a[1] < b[1]


def _identity_extension(model, data):
    """``model`` with one more section at its largest error, an identity section there
    (num = den: exactly the same error). Returns ``(model, max, rms)``."""
    err = relative_error(model, data).values
    w = float(data.omega[int(np.argmax(err))])
    st = model.structure
    new = [1.0, 0.5, w, 1.0, 0.5, w] if st.basis == "second-order" else [1.0 / w, 1.0,
                                                                          1.0 / w, 1.0]
    ext = RationalDelayModel(st.with_sections(st.n_sections + 1),
                             np.concatenate([model.beta, new]))
    same = relative_error(ext, data)
    return ext, float(same.max), float(same.rms)


def _extended(model, res, data, max_iter=EXTEND_MAX_ITER):
    """The previous order's ``model`` with one more section at its largest error
    (:func:`_identity_extension`) polished on all ``data`` with ``res``'s options (at most
    ``max_iter`` iterations; None: the options' ``final_max_iter``).

    Returns ``(model, max, rms, success)``."""
    from .stages import polish

    ext = _identity_extension(model, data)[0]
    opts = res.options
    stall = None
    if opts.loop.init == "relocate":
        from .relocate import STALL_RULE

        ext = _relocated(ext, data, opts.loop, max(res.delay_max, model.delay), res.zeta_min)
        stall = STALL_RULE
    pol = polish(ext, data, method=opts.solver, loop=opts.loop,
                 delay_max=max(res.delay_max, model.delay), zeta_min=res.zeta_min,
                 max_iter=max_iter, stall=stall)
    stats = relative_error(pol.model, data)
    return pol.model, float(stats.max), float(stats.rms), bool(pol.result.success)


def _relocated(model, data, loop, delay_max, zeta_min):
    """``model`` or, when its cost on ``data`` is lower, the vector-fit relocation of all
    its sections at its delay (:func:`~freqid_casadi.fitting.relocate.relocated_start`; the
    sequential loop's init="relocate")."""
    from .relocate import relocated_start
    from .stages import polish_start

    param, z0 = polish_start(model, data, loop=loop, delay_max=delay_max, zeta_min=zeta_min)
    found = relocated_start(param, data, z0, zeta_min)
    return model if found is None else found[0].to_model(found[1])

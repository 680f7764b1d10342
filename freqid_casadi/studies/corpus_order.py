"""The automatic order on the corpus, replayable: one fit per order, then any rule (issue 26).

``n_sections="auto"`` fits N = 1, 2, ... and decides from each order's residual (its RMS
and roughness ratio) and poles (:mod:`freqid_casadi.fitting.order`). Those per-order facts
do not depend on the rule, so :func:`ladder` fits a noisy corpus case at every order up to
``true + EXTRA`` once and keeps them; :func:`replay` runs the rule of
:func:`~freqid_casadi.fitting.order.decide` over them, exactly as ``choose_order`` does over
live fits, and says which order it chose (or that it needed an order the ladder lacks). A
rule can then be judged on many cases for the cost of fitting them once.
"""

import json
import multiprocessing
import time
import warnings

import numpy as np

from ..errors import DataError, StructureError
from ..fitting.fit import fit
from ..fitting.order import MAX_SECTIONS, OrderStep, explaining_step, fit_step
from ..report.folder import code_fingerprint
from ..systems.corpus import FAMILIES, case
from .corpus import (CPU_BUDGET, FLOOR_FACTOR, FULL_CASES, SUBSET_EVERY, TimeLimit, _budget,
                     json_lines)

__all__ = ["EXTRA", "SUBSET_ROUNDS", "RULES", "ladder", "run_ladders", "replay", "judge",
           "order_tasks"]

#: Orders past the true one a ladder fits (a choice above true + 1 is a miss whatever it
#: is, and a rule needs N + 1 (and its patience) to decide on N).
EXTRA = 3


#: The rounds of the corpus run's automatic-order subset (``SUBSET_EVERY``, 300 cases).
SUBSET_ROUNDS = tuple(range(0, -(-FULL_CASES // len(FAMILIES)), SUBSET_EVERY))


def order_tasks(seed=0, rounds=SUBSET_ROUNDS, max_points=120):
    """``(index, seed, max_points)`` of the noisy cases of the given rounds of the nine
    families (round r: indices 9 r ... 9 r + 8; rounds 0, 8, 16, 24, 32 are the corpus
    run's automatic-order subset).

    Parameters
    ----------
    seed : int
        Corpus seed.
    rounds : iterable of int
        Rounds of the nine families.
    max_points : int
        Points per case at most.

    Returns
    -------
    list of tuple
    """
    out = []
    for r in rounds:
        for i in range(len(FAMILIES) * r, len(FAMILIES) * (r + 1)):
            if case(i, seed, max_points=max_points).noise > 0:
                out.append((i, seed, max_points))
    return out


def ladder(task, top=None):
    """Fit case ``task = (index, seed, max_points)`` at N = 1 ... true + EXTRA sections
    (``top`` if given; default options otherwise), each within the corpus run's CPU budget.

    Parameters
    ----------
    task : tuple
        ``(index, seed, max_points)`` of :func:`order_tasks`.
    top : int, optional
        Largest number of sections fitted (default true + :data:`EXTRA`).

    Returns
    -------
    dict
        The case (name, family, true sections, noise, points, in_class) and ``orders``: per
        order ``n_sections, rms, ratio, success, status, poles`` (pairs re, im) and, when
        the fit offers a ``zeros="free"`` alternative, ``free`` (its ``rms, ratio,
        success, status, poles``), or ``error`` (the exception, then the ladder ends).
    """
    index, seed, max_points = task
    c = case(index, seed, max_points=max_points)
    top = min(MAX_SECTIONS, c.n_sections + EXTRA) if top is None else int(top)
    out = dict(task=list(task), case=c.name, family=c.family, true_sections=c.n_sections,
               noise=c.noise, n_points=c.n_points, in_class=c.in_class,
               code=code_fingerprint(), orders=[])
    for n in range(1, top + 1):
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = fit(c.data, n_sections=n, progress=_budget(CPU_BUDGET))
        except (StructureError, DataError, TimeLimit) as exc:
            out["orders"].append(dict(n_sections=n, error=f"{type(exc).__name__}: {exc}"[:200]))
            break
        row = dict(n_sections=n, **_numbers(res), wall_time=time.perf_counter() - t0)
        alt = res.alternatives.get("zeros=free")
        if alt is not None:
            row["free"] = _numbers(alt)
        out["orders"].append(row)
    out["omega"] = [float(c.data.omega[0]), float(c.data.omega[-1])]
    return out


def _numbers(res):
    step = fit_step(res)
    return dict(rms=step.rms, ratio=step.ratio, local_ratio=step.local_ratio,
                success=step.success, status=str(res.status),
                poles=[[float(z.real), float(z.imag)] for z in res.model.poles()])


def run_ladders(tasks, path, workers=2, progress=None):
    """:func:`ladder` of every task not yet in the JSON-lines file ``path``, appended to it
    as each ends; returns every ladder in the file that belongs to ``tasks``.

    Parameters
    ----------
    tasks : list of tuple
        :func:`order_tasks`.
    path : str
        JSON-lines checkpoint (read, then appended to).
    workers : int
        Worker processes.
    progress : callable, optional
        Receives each new ladder (dict).

    Returns
    -------
    list of dict
    """
    done = {tuple(d["task"]): d for d in json_lines(path, code_fingerprint())}
    todo = [t for t in tasks if tuple(t) not in done]
    if todo:
        ctx = multiprocessing.get_context("spawn")
        with ctx.Pool(workers) as pool:
            for d in pool.imap_unordered(ladder, todo):
                with open(path, "a", encoding="utf-8") as f:
                    f.write(json.dumps(d) + "\n")
                done[tuple(d["task"])] = d
                if progress is not None:
                    progress(d)
    return [done[tuple(t)] for t in tasks if tuple(t) in done]


class _Beyond(Exception):
    pass


def replay(lad, decide=None, *, free_zeros=True, **kw):
    """The order ``decide`` (default :func:`freqid_casadi.fitting.order.decide`) chooses
    over a :func:`ladder`: ``(n_sections, reason)``, or ``(None, "beyond")`` when the rule
    asked for an order the ladder did not fit (a choice above ``true + 1`` in any case
    unless the ladder ended at the data limit).

    Parameters
    ----------
    lad : dict
        A :func:`ladder`.
    decide : callable, optional
        The stopping rule, as :func:`freqid_casadi.fitting.order.decide`.
    free_zeros : bool
        Read an order from its ``zeros="free"`` alternative where
        :func:`~freqid_casadi.fitting.order.explaining_step` does (as ``choose_order``);
        False: from the minimum-phase fit alone (the rule before it).
    **kw
        Passed to ``decide``.

    Returns
    -------
    (int or None, str)
    """
    from ..fitting import order as _order
    decide = decide or _order.decide
    orders = {o["n_sections"]: o for o in lad["orders"]}
    omega = np.array(lad["omega"])
    steps, poles = [], []
    for n in range(1, MAX_SECTIONS + 1):
        o = orders.get(n)
        if o is None:
            return None, "beyond"
        if "error" in o:
            if not steps:
                return None, "error"
            k, reason = decide(steps, poles, omega, lad["n_points"], end="data-limit")
            return steps[k].n_sections, reason
        free = o.get("free") if free_zeros else None
        step = explaining_step(
            OrderStep(n, o["rms"], o["ratio"], o["success"],
                      local_ratio=o.get("local_ratio", 0.0)),
            free and OrderStep(n, free["rms"], free["ratio"], free["success"],
                               local_ratio=free.get("local_ratio", 0.0)))
        steps.append(step)
        poles.append(np.array([complex(a, b) for a, b in (free if step.free else o)["poles"]]))
        verdict = decide(steps, poles, omega, lad["n_points"], **kw)
        if verdict is not None:
            k, reason = verdict
            return steps[k].n_sections, reason
    k, reason = decide(steps, poles, omega, lad["n_points"], end="max-sections")
    return steps[k].n_sections, reason


def judge(ladders, decide=None, **options):
    """Replay ``decide`` over every ladder: list of dicts (case, family, true, chosen,
    reason, right: chosen in [true, true + 1], below, above, subset: a case of
    :data:`SUBSET_ROUNDS`, floor: its fit at the true order reaches the noise floor, RMS at
    most ``FLOOR_FACTOR`` times the noise, so that a miss is the rule's). A rule that asks
    for an order the ladder lacks chose above
    true + 1 (the ladder reaches true + :data:`EXTRA`).

    Parameters
    ----------
    ladders : list of dict
        :func:`ladder` results.
    decide : callable, optional
        As for :func:`replay`.
    **options
        :func:`replay`'s keywords (``free_zeros``).

    Returns
    -------
    list of dict
    """
    out = []
    for d in ladders:
        n, reason = replay(d, decide, **options)
        t = d["true_sections"]
        at_true = next((o for o in d["orders"] if o["n_sections"] == t and "rms" in o), None)
        out.append({"case": d["case"], "family": d["family"], "true": t, "chosen": n,
                    "reason": reason, "right": n is not None and t <= n <= t + 1,
                    "below": n is not None and n < t,
                    "above": n is None and reason == "beyond" or n is not None and n > t + 1,
                    "subset": d["task"][0] // len(FAMILIES) in SUBSET_ROUNDS,
                    "floor": at_true is not None
                    and at_true["rms"] <= FLOOR_FACTOR * d["noise"]})
    return out


#: The rules compared: name -> (decide callable or None for today's, one-line description,
#: :func:`judge`'s options).
RULES = {
    "today": (None, "`freqid_casadi.fitting.order.decide`: one more section counts as an "
                    "improvement when the RMS falls by max(0.1, 12 / M x (sigma / RMS)^2), the "
                    "noise share (sigma / RMS)^2 = 1 / ratio^2 for a structured residual, 1 for "
                    "one consistent with the noise; or, when the lower order's residual is "
                    "consistent with the noise, when the nested-model F-test at level 0.01 "
                    "says so and the RMS falls by at least 3 %. An order whose minimum-phase "
                    "fit is not consistent with the noise is read from the zeros='free' model "
                    "that fit offers, when that reaches at most half its RMS "
                    "(`explaining_step`): the search stops where the offered model explains "
                    "the data", {}),
    "previous": (None, "the same, every order read from its minimum-phase fit alone (the "
                       "rule of the previous results/corpus-order)", {"free_zeros": False}),
}

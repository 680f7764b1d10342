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
import math
import multiprocessing
import time
import types
import warnings

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, StructureError
from ..fitting.fit import fit
from ..fitting.order import (MAX_SECTIONS, OrderStep, explaining_step, fit_step,
                             resonance_count)
from ..report.folder import code_fingerprint
from ..systems.corpus import FAMILIES, case
from .corpus import (CPU_BUDGET, FLOOR_FACTOR, FULL_CASES, SUBSET_EVERY, TimeLimit, _budget,
                     json_lines)

__all__ = ["EXTRA", "SUBSET_ROUNDS", "RULES", "ladder", "run_ladders", "replay", "judge",
           "order_tasks", "many_mode_case", "many_mode_tasks", "MANY_MODES"]

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


#: Modes of the many-mode cases, by index (:func:`many_mode_case`).
MANY_MODES = (6, 8, 10, 12, 14, 16)


def many_mode_case(index, seed=0, n_points=400):
    """A lightly damped flexible structure with many modes, measured collocated: the
    modes' natural frequencies log-uniform over 2.5 decades, damping ratios log-uniform in
    [0.005, 0.05], positive residues (so poles and zeros interlace: minimum phase), a
    feedthrough in every other case, a delay up to a tenth of a turn at the top frequency
    and flat complex Gaussian relative noise of 0.3-3 %, at ``n_points`` log-spaced
    frequencies over 3 decades around the modes. The corpus's families have at most 6
    modes; these test the order search where one section is one mode of many.

    Parameters
    ----------
    index, seed : int
        Case ``index`` has ``MANY_MODES[index % 6]`` modes; its draws come from
        ``numpy.random.default_rng([seed, index, 6])``.
    n_points : int

    Returns
    -------
    types.SimpleNamespace
        ``name, family ("many-modes"), n_sections, noise, n_points, in_class (True), data``
        (:class:`~freqid_casadi.core.data.FrequencyData`, rad/s).
    """
    rng = np.random.default_rng([int(seed), int(index), 6])
    modes = MANY_MODES[index % len(MANY_MODES)]
    wn = np.sort(np.exp(rng.uniform(0.0, 2.5 * math.log(10), modes)))
    zeta = np.exp(rng.uniform(math.log(0.005), math.log(0.05), modes))
    residue = rng.uniform(0.3, 1.0, modes)
    omega = np.geomspace(wn[0] / 3, wn[-1] * 3, int(n_points))
    s = 1j * omega
    g = np.sum(residue[:, None] * wn[:, None] ** 2
               / (s ** 2 + 2 * zeta[:, None] * wn[:, None] * s + wn[:, None] ** 2), axis=0)
    g = g + (0.05 * rng.uniform(0.2, 1.0) if index % 2 else 0.0)
    g = g * np.exp(-s * rng.uniform(0.0, 0.1) * 2 * math.pi / omega[-1])
    noise = math.exp(rng.uniform(math.log(0.003), math.log(0.03)))
    n = (rng.standard_normal(omega.size) + 1j * rng.standard_normal(omega.size)) / math.sqrt(2)
    name = f"many-modes-{index}"
    return types.SimpleNamespace(
        name=name, family="many-modes", n_sections=modes, noise=noise,
        n_points=omega.size, in_class=True,
        data=FrequencyData(omega, g * (1 + noise * n), name, None))


def many_mode_tasks(n, seed=0, n_points=400):
    """Tasks ``("many-modes", index, seed, n_points)`` of :func:`ladder` for the first
    ``n`` many-mode cases (:func:`many_mode_case`).

    Parameters
    ----------
    n, seed, n_points : int

    Returns
    -------
    list of tuple
    """
    return [("many-modes", i, int(seed), int(n_points)) for i in range(int(n))]


def _case(task):
    if task[0] == "many-modes":
        return many_mode_case(*task[1:])
    index, seed, max_points = task
    return case(index, seed, max_points=max_points)


def ladder(task, top=None):
    """Fit case ``task = (index, seed, max_points)`` at N = 1 ... true + EXTRA sections
    (``top`` if given; default options otherwise), each within the corpus run's CPU budget.

    Parameters
    ----------
    task : tuple
        ``(index, seed, max_points)`` of :func:`order_tasks`, or a many-mode case's
        ``("many-modes", index, seed, n_points)`` (:func:`many_mode_tasks`).
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
    c = _case(task)
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


def replay(lad, decide=None, *, free_zeros=True, peaks=True, **kw):
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
    peaks : bool
        Do not stop for want of improvement below the data's resonance peaks (as
        ``choose_order``, counted on the ladder's case); False: the rule before it.
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
    if peaks:
        data = _case(lad["task"]).data
        kw = dict(kw, peaks=resonance_count(data.omega, data.response, data.weights))
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
                    "subset": isinstance(d["task"][0], int)
                    and d["task"][0] // len(FAMILIES) in SUBSET_ROUNDS,
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
                    "the data. It does not stop for want of improvement below as many "
                    "sections as the data show resonance peaks (`resonance_count`)", {}),
    "previous": (None, "the same without the resonance peaks (the rule of the previous "
                       "results/corpus-order)", {"peaks": False}),
    "before free zeros": (None, "the previous rule, every order read from its "
                                "minimum-phase fit alone", {"peaks": False,
                                                            "free_zeros": False}),
}

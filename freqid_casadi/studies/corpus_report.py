"""Report folder of the validation corpus run (:mod:`freqid_casadi.studies.corpus`).

``report.md`` (first line: the command), ``report.json`` (the summary and every fit),
``fits.csv`` (one row per fit) and ``corpus.png`` (per family: fraction at the floor for
each configuration; RMS against the noise level for every fit); with ``measured`` also the
section of the shipped measured FRFs (:mod:`freqid_casadi.studies.corpus_measured`, key
``"measured"`` of report.json), and with ``measured_only`` that section alone.
"""

import csv
import io
import json
import os
import time

import numpy as np

from ..report.environment import computed_on_lines, environment
from ..report.formatting import generated_by_line, json_safe, markdown_table, number
from ..report.folder import atomic_write_text, check_out_dir, report_folder
from ..systems.corpus import FAMILIES
from .corpus import (AUTO, CONFIGS, DENSE, DISHONEST_FACTOR, EXACT_FLOOR, FLOOR_FACTOR,
                     record_dicts, run_corpus, summarize)
from .corpus_measured import measured_dicts, render_measured, run_measured

__all__ = ["write_corpus_report", "render_corpus", "rerender_corpus_report"]


def _pct(x):
    return "—" if x is None or not np.isfinite(x) else f"{100 * x:.0f} %"


def _table(summary, config):
    rows = []
    for fam, s in summary[config].items():
        rows.append([fam, s["n"], _pct(s["at_floor"]), _pct(s["at_floor_truth"]),
                     _pct(s["sign_right"]), _pct(s["class_right"]), _pct(s["claims_ok"]),
                     s["dishonest"], s["errors"], number(s["time_median"], 2),
                     number(s["time_max"], 2)])
    return markdown_table(rows, ["family", "fits", "at floor (data)", "at floor (truth)",
                                 "sign right", "class right", "claims ok",
                                 "dishonest", "errors", "time median (s)", "time max (s)"])


def _compare(summary):
    configs = [c for c in CONFIGS if c in summary]
    rows = []
    for fam in list(FAMILIES) + ["in-class cases", "outside the class", "all"]:
        row = [fam]
        for c in configs:
            s = summary[c].get(fam)
            row.append("—" if s is None else
                       f"{_pct(s['at_floor'])} / {s['dishonest']} / {number(s['time_median'], 2)}")
        rows.append(row)
    return markdown_table(rows, ["family"] + [f"{c}: floor / dishonest / median s"
                                              for c in configs])


def _auto_table(summary):
    rows = []
    for fam, s in summary[AUTO].items():
        rows.append([fam, s["n"], _pct(s["order_right"]), s["order_below"], s["order_above"],
                     _pct(s["at_floor"]), s["dishonest"], number(s["time_median"], 2)])
    return markdown_table(rows, ["family", "noisy cases", "order in [true, true+1]",
                                 "below", "above", "at floor (data)", "dishonest",
                                 "time median (s)"])


def _verdict(summary, records):
    """One line per candidate: its floor fractions and dishonest fits against today's on
    the same cases, and its time."""
    if "today" not in summary:
        return []
    out = []
    for c in [k for k in CONFIGS if k in summary and k != "today"]:
        mine = [r for r in records if r["config"] == c]
        names = {r["case"] for r in mine}
        base = [r for r in records if r["config"] == "today" and r["case"] in names]
        a, b = _floor_stats(mine), _floor_stats(base)
        out.append(f"- `{c}` ({len(mine)} fits): in-class cases at the floor "
                   f"{_pct(a['in_class'])} against today's {_pct(b['in_class'])} on the same "
                   f"cases, all {_pct(a['all'])} against {_pct(b['all'])}; claims ok "
                   f"{_pct(a['claims_ok'])} against {_pct(b['claims_ok'])}; dishonest "
                   f"{a['dishonest']} against {b['dishonest']}; median time "
                   f"{number(a['median_time'], 2)} s against {number(b['median_time'], 2)} s, "
                   f"in all {number(a['total_time'], 3)} s against "
                   f"{number(b['total_time'], 3)} s." + _moved(mine, base))
    if AUTO in summary:
        s = summary[AUTO]["all"]
        ok = _identifiable(records)
        right = [0 <= r["n_sections"] - r["true_sections"] <= 1 for r in ok]
        out.append(f"- `{AUTO}` ({s['n']} noisy cases): order in [true, true + 1] in "
                   f"{_pct(s['order_right'])} ({s['order_below']} below, {s['order_above']} "
                   f"above), median time {number(s['time_median'], 2)} s; on the "
                   f"{len(ok)} of them whose fit at the true order (today's defaults) "
                   f"reaches the floor: {_pct(np.mean(right) if right else np.nan)}.")
    return out


def _identifiable(records):
    """The automatic-order fits of the cases whose true order is identifiable: today's
    fit at the true order reaches the floor."""
    floor = {r["case"] for r in records if r["config"] == "today" and r["at_floor"]}
    return [r for r in records if r["config"] == AUTO and r["case"] in floor
            and not r["error"]]


def _floor_stats(recs):
    """{in_class, all: fractions at the floor; dishonest: count; median_time, total_time:
    seconds per fit and summed (finite times); claims_ok: fraction} of the records."""
    def mean(values):
        return float(np.mean(values)) if values else float("nan")

    return {"in_class": mean([r["at_floor"] for r in recs if r["in_class"]]),
            "all": mean([r["at_floor"] for r in recs]),
            "dishonest": int(sum(r["dishonest"] for r in recs)),
            "median_time": (float(np.median([r["wall_time"] for r in recs])) if recs
                            else float("nan")),
            "claims_ok": mean([r["claims_ok"] for r in recs]),
            "total_time": float(np.sum([r["wall_time"] for r in recs
                                        if np.isfinite(r["wall_time"])]))}


def _moved(mine, base):
    """How far today's fits moved from a candidate's on the same noisy cases at the
    floor, in noise variances: ``M (rms_today^2 - rms_candidate^2) / nu^2`` (positive:
    today's fit is worse), its median and extremes (empty when no case is both)."""
    theirs = {r["case"]: r for r in mine if not r["error"]}
    moved = [r["n_points"] * (r["rms"] ** 2 - theirs[r["case"]]["rms"] ** 2) / r["nu"] ** 2
             for r in base if r["case"] in theirs and r["noise"] > 0 and not r["error"]
             and r["at_floor"] and theirs[r["case"]]["at_floor"]]
    if not moved:
        return ""
    q = np.quantile(moved, [0.0, 0.05, 0.5, 0.95, 1.0])
    return (f" On the {len(moved)} noisy cases both fit to the floor, today's cost is the "
            f"candidate's plus (noise variances, M (RMS^2 - RMS'^2) / ν^2) "
            f"{number(q[2], 2)} at the median, {number(q[1], 2)} .. {number(q[3], 2)} for "
            f"90 % of them, {number(q[0], 2)} .. {number(q[4], 2)} at the extremes "
            "(1 is a move by one standard error).")


def render_corpus(command, summary, meta, records):
    """The Markdown report.

    Parameters
    ----------
    command : str
        First line.
    summary : dict
        :func:`~freqid_casadi.studies.corpus.summarize` of the records.
    meta : dict
        The run: cases, seed, points, fits, workers, wall time.
    records : list of dict
        Every fit (:func:`~freqid_casadi.studies.corpus.record_dicts`).

    Returns
    -------
    str
    """
    lines = [generated_by_line(command), "", "# Validation corpus: the defaults on "
             f"{meta['n_cases']} seeded synthetic FRFs", "",
             f"Corpus `freqid_casadi.systems.corpus(n={meta['n_cases']}, seed={meta['seed']}, "
             f"max_points={meta['max_points']})`: {meta['n_points_total']} points in all "
             f"({meta['n_points_min']}-{meta['n_points_max']} per case); {meta['n_fits']} fits "
             f"on {meta['workers']} worker processes, "
             f"{meta.get('fit_time_total', float('nan')):.0f} s "
             f"of fitting summed over the fits (this command's wall time {meta['wall_time']:.0f}"
             " s; with --resume the fits of the checkpoint are not timed again).", "",
             *computed_on_lines(meta.get("environment")),
             "Every case is fitted at its true order (`fc.fit(data, n_sections=<true>, "
             "**config)`, every other option at its default), by each configuration, in "
             "this one run. Definitions (`freqid_casadi.studies.corpus`):", "",
             f"- noise level ν: the RMS of the case's relative noise, at least {EXACT_FLOOR:g} "
             "(exact data are held to that numerical floor);",
             f"- **at floor (data)**: RMS relative error against the noisy data ≤ "
             f"{FLOOR_FACTOR:g} ν; **at floor (truth)**: RMS of |G_true/G_N − 1| on a log grid "
             f"{DENSE}× denser than the data (between the samples) ≤ {FLOOR_FACTOR:g} ν;",
             "- **claims ok**: `res.status == \"ok\"` when results have a status, else "
             "`res.success`; **dishonest**: claims ok with an RMS above "
             f"{DISHONEST_FACTOR:g} ν;",
             "- **sign right**: the model's gain sign is the system's; **class right**: at the "
             "floor, or outside the class with a diagnostic naming the cause (`integrator` "
             "for undeclared poles at the origin, `non-minimum-phase` for right-half-plane "
             "zeros).", "",
             "## Today's defaults against the candidates", "", *_verdict(summary, records),
             "",
             "Per family: fraction at the floor (data) / dishonest fits / median time per fit.",
             "", _compare(summary), ""]
    for config in [c for c in CONFIGS if c in summary]:
        lines += [f"## `{config}`", "", _table(summary, config), ""]
    if AUTO in summary:
        lines += [f"## Automatic order (`{AUTO}`, noisy cases)", "",
                  "`fc.fit(data, n_sections=\"auto\")`, today's other defaults: the smallest "
                  "order whose residual is no rougher than white noise, not bettered by one "
                  "more section, its in-band poles kept by it (`freqid_casadi.fitting.order`).",
                  "", _auto_table(summary), ""]
    worst = sorted((r for r in records if r["dishonest"]), key=lambda r: -r["rms"] / r["nu"])
    if worst:
        lines += ["## Dishonest fits (claims ok, RMS > 10 ν), worst first", "",
                  markdown_table([[r["case"], r["config"], number(r["rms"], 3),
                                   number(r["noise"], 3), ", ".join(r["diagnostics"]) or "—"]
                                  for r in worst[:25]],
                                 ["case", "config", "RMS", "noise", "diagnostics"]), ""]
    lines += ["![per family](corpus.png)", ""]
    return "\n".join(lines)


def _figure(summary, records):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    auto = [r for r in records if r["config"] == AUTO and not r["error"]]
    fig, axes = plt.subplots(1, 3 if auto else 2, figsize=(19 if auto else 14, 5.5),
                             gridspec_kw={"width_ratios": [3, 3, 1.6] if auto else [1, 1]})
    a, b = axes[0], axes[1]
    configs = [c for c in CONFIGS if c in summary]
    fams = [f for f in FAMILIES if f in summary[configs[0]]]
    x = np.arange(len(fams))
    width = 0.8 / len(configs)
    for k, c in enumerate(configs):
        a.bar(x + k * width, [summary[c].get(f, {}).get("at_floor", np.nan) for f in fams],
              width, label=f"{c} ({summary[c]['all']['n']} fits)")
    a.set_xticks(x + 0.4 - width / 2)
    a.set_xticklabels(fams, rotation=35, ha="right")
    a.set_ylabel("fraction at the noise floor (data)")
    a.set_ylim(0, 1.05)
    a.legend(fontsize=8, loc="lower left")
    a.set_title("per family, at the true order (the candidates on the subset)")
    for k, c in enumerate(configs):
        sel = [r for r in records if r["config"] == c and np.isfinite(r["rms"])]
        a_ok = np.array([r["claims_ok"] for r in sel], bool)
        nu = np.array([r["nu"] for r in sel])
        rms = np.maximum([r["rms"] for r in sel], 1e-8)   # exact fits shown at 1e-8
        b.scatter(nu[a_ok] * (1.06 ** k), rms[a_ok], s=10, marker="o", alpha=0.6,
                  label=f"{c}: claims ok")
        b.scatter(nu[~a_ok] * (1.06 ** k), rms[~a_ok], s=14, marker="x", alpha=0.6,
                  label=f"{c}: does not")
    grid = np.logspace(np.log10(EXACT_FLOOR) - 0.2, np.log10(0.06), 20)
    b.plot(grid, FLOOR_FACTOR * grid, "k--", lw=1, label=f"{FLOOR_FACTOR:g} ν (floor)")
    b.plot(grid, DISHONEST_FACTOR * grid, "r:", lw=1, label=f"{DISHONEST_FACTOR:g} ν")
    b.set_xscale("log")
    b.set_yscale("log")
    b.set_xlabel("noise level ν (relative RMS; exact data at 1e-4)")
    b.set_ylabel("RMS relative error against the data (floored at 1e-8)")
    b.set_title("every fit")
    b.legend(fontsize=6, loc="lower right")
    if auto:
        diff = np.array([r["n_sections"] - r["true_sections"] for r in auto])
        edges = np.arange(diff.min() - 0.5, diff.max() + 1.5)
        axes[2].hist(diff, bins=edges, color="0.5")
        axes[2].axvspan(-0.5, 1.5, color="g", alpha=0.15, label="[true, true + 1]")
        axes[2].set_xlabel("chosen - true sections")
        axes[2].set_ylabel("noisy cases")
        axes[2].set_title("n_sections='auto'")
        axes[2].legend(fontsize=8)
    fig.tight_layout()
    return fig


def _csv(records):
    buf = io.StringIO()
    keys = list(records[0]) if records else []
    w = csv.DictWriter(buf, keys)
    w.writeheader()
    for r in records:
        w.writerow({k: (";".join(map(str, v)) if isinstance(v, (list, tuple)) else v)
                    for k, v in r.items()})
    return buf.getvalue()


def write_corpus_report(out_dir, *, command, n, seed=0, max_points=5000, workers=2,
                        configs=None, auto=True, force=False, progress=None,
                        checkpoint=None, measured=False, measured_only=False,
                        measured_progress=None, measured_names=None,
                        measured_max_sections=None):
    """Run the corpus (:func:`~freqid_casadi.studies.corpus.run_corpus`) and write its
    report folder.

    Parameters
    ----------
    out_dir : str or os.PathLike
    command : str
        First line of report.md.
    n, seed, max_points, workers, configs, auto, progress, checkpoint
        Passed to :func:`run_corpus`.
    force : bool
        Replace an existing ``out_dir`` (only once the new report is complete).
    measured : bool
        Also fit the shipped measured FRFs
        (:func:`~freqid_casadi.studies.corpus_measured.run_measured`, ``workers`` processes)
        and add their section.
    measured_only : bool
        Fit only the measured FRFs: report.md and report.json hold that section alone.
    measured_progress, measured_names, measured_max_sections : optional
        Passed to :func:`run_measured` as its ``progress``, ``names`` and
        ``max_sections`` (which sets, and a cap on their orders: a quicker run).

    Returns
    -------
    dict
        The summary, as in report.json.
    """
    check_out_dir(out_dir, force)
    run_kw = {"workers": workers, "progress": measured_progress, "names": measured_names,
              "max_sections": measured_max_sections}
    if measured_only:
        return _write_measured_only(out_dir, command, force, run_kw)
    from ..systems.corpus import corpus

    cases = corpus(n, seed, max_points=max_points)
    t0 = time.perf_counter()
    records = record_dicts(run_corpus(n, seed, max_points=max_points, workers=workers,
                                      configs=configs, auto=auto, progress=progress,
                                      checkpoint=checkpoint))
    wall = time.perf_counter() - t0
    points = [c.n_points for c in cases]
    meta = {"n_cases": n, "seed": seed, "max_points": max_points, "workers": workers,
            "n_fits": len(records), "wall_time": wall,
            "fit_time_total": float(sum(r["wall_time"] for r in records)),
            "n_points_total": int(sum(points)),
            "n_points_min": int(min(points)), "n_points_max": int(max(points)),
            "environment": environment()}
    summary = summarize([_Rec(r) for r in records])
    out = {"command": command, "meta": meta, "summary": summary, "fits": records}
    if measured:
        t1 = time.perf_counter()
        out["measured"] = measured_dicts(run_measured(**run_kw))
        meta["measured_wall_time"] = time.perf_counter() - t1
    out = json_safe(out)
    with report_folder(out_dir, force) as (tmp, _):
        fig = _figure(summary, records)
        fig.savefig(os.path.join(tmp, "corpus.png"), dpi=110)
        import matplotlib.pyplot as plt

        plt.close(fig)
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(out, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "fits.csv"), _csv(records))
        atomic_write_text(os.path.join(tmp, "report.md"),
                          render_corpus(command, summary, meta, records)
                          + _measured_text(out.get("measured")))
    return out


def _measured_text(records):
    """The measured section appended to report.md ("" without one)."""
    return "" if records is None else "\n" + "\n".join(render_measured(records))


def _write_measured_only(out_dir, command, force, run_kw):
    """``write_corpus_report(..., measured_only=True)``: report.md and report.json of the
    measured section alone."""
    t0 = time.perf_counter()
    records = measured_dicts(run_measured(**run_kw))
    meta = {"workers": run_kw["workers"], "measured_wall_time": time.perf_counter() - t0,
            "measured_max_sections": run_kw["max_sections"], "environment": environment()}
    out = json_safe({"command": command, "meta": meta, "measured": records})
    with report_folder(out_dir, force) as (tmp, _):
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(out, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), _measured_only_md(out))
    return out


def _measured_only_md(out):
    head = [generated_by_line(out["command"]), "",
            "# Validation corpus: the measured FRFs only", "",
            f"{len(out['measured'])} fits on {out['meta']['workers']} worker processes, "
            f"{out['meta']['measured_wall_time']:.0f} s wall time (the synthetic corpus is "
            "not in this run: `python scripts/corpus.py` without --measured-only).", "",
            *computed_on_lines(out["meta"].get("environment"))]
    return "\n".join(head + render_measured(out["measured"]))


def rerender_corpus_report(out_dir):
    """Write report.md, fits.csv and corpus.png of ``out_dir`` again from its report.json
    (no fit is run; the first line keeps the command that made the fits).

    Parameters
    ----------
    out_dir : str or os.PathLike
        A folder written by :func:`write_corpus_report`.

    Returns
    -------
    dict
        The report.json contents.
    """
    path = os.path.join(out_dir, "report.json")
    with open(path, encoding="utf-8") as f:
        out = json.load(f)
    if "fits" not in out:                   # a --measured-only report
        atomic_write_text(os.path.join(out_dir, "report.md"), _measured_only_md(out))
        return out
    records = out["fits"]
    summary = summarize([_Rec(r) for r in records])
    fig = _figure(summary, records)
    fig.savefig(os.path.join(out_dir, "corpus.png"), dpi=110)
    import matplotlib.pyplot as plt

    plt.close(fig)
    atomic_write_text(os.path.join(out_dir, "fits.csv"), _csv(records))
    atomic_write_text(os.path.join(out_dir, "report.md"),
                      render_corpus(out["command"], summary, out["meta"], records)
                      + _measured_text(out.get("measured")))
    return out


class _Rec:
    """A record dict read as attributes (for :func:`summarize`)."""

    def __init__(self, d):
        self.__dict__.update(d)

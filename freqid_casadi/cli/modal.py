"""The ``freqid modal`` command: shared poles, stabilization diagram, modal table (layer L6).

Usage::

    freqid modal FILES... --orders 2:40:2 --out DIR [--force] [--freq-unit hz|rad/s]
                 [--columns LIST] [--delay per-channel|shared|none]
                 [--zeros free|minimum-phase|LIST] [--integrator] [--freq-tol 0.01]
                 [--damping-tol 0.10] [--min-stable 3] [--max-iter 100]
                 [--channel-sections K] [--balance-channels] [--estimator rational|full]
                 [--jobs N]
                 [--coordinates X1,X2,...|FILE] [--reference-shapes FILE]

Reads one FRF per file (:func:`freqid_casadi.load`; all on one omega grid; every
frequency-response record of a UFF file, and every response of a ``.mat`` file (the
channels of an FRF matrix), each a channel: :func:`freqid_casadi.load_all`), estimates
every order of ``--orders`` with shared poles
(:func:`freqid_casadi.modal.survey.stabilization`: shared-pole vector fitting at each
order, the selected modes then fitted once with ``fit_shared``; ``--estimator full`` fits
every order with ``fit_shared``; with
``--channel-sections K`` every channel also has K sections of its own standing in for the
out-of-band modes, not counted in the order and not in the diagram) and
writes the report folder ``DIR`` (built in a temporary folder, then moved into place; an
existing ``DIR`` is refused without ``--force``):

- ``summary.md`` (first line: the command), ``summary.json``;
- ``modes.csv``, ``modes.md``: the automatically selected modes (frequency, damping, each
  channel's residue), from the highest order's fit;
- ``stabilization.csv``, ``stabilization.png``: every pole of every order with its status;
- ``shapes.csv``, ``shape_<k>.png``: the selected modes' shapes (every channel's modal
  constant, phase-aligned, largest component +1; each mode's MPC and MPD), against the
  channels' ``--coordinates`` when given;
- ``mac.csv``: with ``--reference-shapes FILE`` (one row per channel, one column per
  reference mode, numbers only or a header line), the MAC matrix of the selected shapes
  (rows) against the reference shapes (columns);
- ``bode_<channel>.png``, ``model_<channel>.json``: data and model, the fit of the selected
  modes (of the highest order with ``--estimator full``; none when no mode is selected).
"""

import json
import os
import re
import warnings

import numpy as np

from .._textio import atomic_write_text, md_cell, md_text
from .common import add_data_options
from ..errors import OptionError
from ..options import IpoptOptions

__all__ = ["add_cli", "run_cli", "modal_words", "NAME"]

#: Name of the command.
NAME = "modal"


def add_cli(subparsers):
    """Add the ``modal`` subparser to ``subparsers``; return it.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``freqid`` command's subparsers.
    """
    p = subparsers.add_parser(
        NAME, help="many FRFs of one structure: shared poles, stabilization diagram, "
                   "modal table",
        description="Fit several FRFs (one file each, same frequency grid) with one shared "
                    "set of poles at every order of --orders, mark each pole new / stable "
                    "in frequency / stable in frequency and damping, select the stable "
                    "modes and write a report folder.")
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="FRF files (text/CSV, .npz, .mat, .uff/.unv, .s1p/.s2p, read as by "
                        "'freqid fit'; see its --help for the columns and units); a UFF "
                        "file gives every frequency-response record it holds, one channel "
                        "each (--record K: only that one), a .mat file every response "
                        "(each column of an FRF matrix H: H(:,1), H(:,2), ...; "
                        "--parameter 'H(:,2)': only that one)")
    add_data_options(p, records=True, weights=False)
    p.add_argument("--orders", default="2:40:2", metavar="START:STOP:STEP",
                   help="model orders (number of shared poles, even), stop included, or a "
                        "comma list (default 2:40:2)")
    p.add_argument("--out", required=True, metavar="DIR", help="report folder to create")
    p.add_argument("--force", action="store_true", help="replace an existing DIR")
    p.add_argument("--delay", default="none", choices=["per-channel", "shared", "none"],
                   help="delays: one per channel, one for all, or none (default none)")
    p.add_argument("--zeros", default="free", metavar="KIND[,KIND...]",
                   help="free (default: right-half-plane zeros allowed, as a "
                        "non-collocated sensor's FRF has them; the table says which "
                        "channels' models are minimum phase) or minimum-phase; one value "
                        "or one per channel (before 2026-12 the default was "
                        "minimum-phase)")
    p.add_argument("--integrator", action="store_true", help="a factor 1/s in every channel")
    p.add_argument("--freq-tol", type=float, default=0.01,
                   help="relative frequency tolerance of a stable pole (default 0.01)")
    p.add_argument("--damping-tol", type=float, default=0.10,
                   help="relative damping tolerance of a stable pole (default 0.10)")
    p.add_argument("--min-stable", type=int, default=3,
                   help="orders a selected mode must have stayed stable (default 3)")
    p.add_argument("--max-iter", type=int, default=100,
                   help="IPOPT iterations per stage of the fit of the selected modes (of "
                        "every order with --estimator full; twice in the final polish; "
                        "default 100: orders above the true one have flat directions)")
    p.add_argument("--estimator", default="rational", choices=["rational", "full"],
                   help="each order of the diagram: shared-pole vector fitting, the selected "
                        "modes then fitted once (rational, default), or a whole shared-pole "
                        "fit per order (full, the slower survey of earlier versions)")
    p.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="worker processes for the orders (default 1; n_jobs of "
                        "stabilization)")
    p.add_argument("--channel-sections", type=int, default=0, metavar="K",
                   help="sections of each channel's own beside the shared ones, standing in "
                        "for the modes outside the band as that channel sees them (the "
                        "upper/lower residuals of modal analysis); their poles are not "
                        "modes (default 0)")
    p.add_argument("--balance-channels", action="store_true",
                   help="reweight so that no channel's max rel. error exceeds that of its "
                        "own single-channel fit (C extra fits in the fit of the selected "
                        "modes, or per order with --estimator full)")
    p.add_argument("--coordinates", metavar="X1,X2,...|FILE",
                   help="where each channel was measured (e.g. the hammer positions), one "
                        "number per file as a comma list, or a text/CSV file with one row "
                        "per channel (1-3 numbers); used for the shapes' CSV and figures")
    p.add_argument("--reference-shapes", metavar="FILE",
                   help="reference mode shapes (text/CSV: one row per channel, one column "
                        "per mode, an optional header line): the MAC of the selected "
                        "shapes against them is written to mac.csv and summary.md")
    return p


def _number_table(path, what):
    """Rows of numbers of a small text/CSV file (a first non-numeric line skipped)."""
    try:
        with open(path, encoding="utf-8-sig") as f:
            lines = [ln.strip() for ln in f if ln.strip() and not ln.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise OptionError(f"{what}: cannot read {path!r} ({exc}); give a UTF-8 text file "
                          "of numbers") from None
    rows = []
    for k, ln in enumerate(lines):
        try:
            rows.append([float(t) for t in re.split(r"[,;\s]+", ln) if t])
        except ValueError:
            if k == 0:
                continue                                  # a header line
            raise OptionError(f"{what}: line {k + 1} of {path!r} is not numbers: "
                              f"{ln[:60]!r}") from None
    if not rows or len({len(r) for r in rows}) != 1:
        raise OptionError(f"{what}: {path!r} must hold rows of equally many numbers, one "
                          "row per channel")
    return np.array(rows)


def _coordinates(text, n):
    """The channels' coordinates (n, d) from ``--coordinates`` (None when not given)."""
    if text is None:
        return None
    if os.path.isfile(text):
        coords = _number_table(text, "--coordinates")
    else:
        try:
            coords = np.array([float(t) for t in str(text).split(",")])[:, None]
        except ValueError:
            raise OptionError(f"--coordinates must be a comma list of numbers (one per "
                              f"channel) or a file, got {text!r}") from None
    if coords.shape[0] != n:
        raise OptionError(f"--coordinates needs one entry per channel ({n}: a file each, or "
                          f"each FRF record of a UFF file), got {coords.shape[0]}")
    return coords


def _reference(path, n):
    """Reference shapes (modes, n) from ``--reference-shapes`` (None when not given)."""
    if path is None:
        return None
    ref = _number_table(path, "--reference-shapes")
    if ref.shape[0] != n:
        raise OptionError(f"--reference-shapes: {path!r} has {ref.shape[0]} rows; it needs "
                          f"one row per channel ({n}), one column per mode")
    return ref.T


def _file_channels(args, path):
    """The FRFs of one file (:func:`freqid_casadi.io.loaders.load_all`): its one data
    set, every frequency-response record of a UFF file (a modal test's file holds one per
    channel; ``--record K`` reads one), every response of a ``.mat`` or ``.npz`` file (an
    FRF matrix's channels; ``--parameter`` reads one) or of a table whose header gives
    several (``--columns`` reads one)."""
    from .common import load_data, load_options, refuse_flags
    from ..io.loaders import load_all

    opts = load_options(args)
    if any(opts.get(k) is not None for k in ("record", "parameter", "columns")):
        return [load_data(args, path)]
    refuse_flags(path, opts)
    return load_all(path, freq_unit=opts.get("freq_unit"), columns=opts.get("columns"),
                    band=opts.get("band"))


#: The least share of the largest grid the frequencies all channels share must keep for
#: the channels to be cut to them (fewer: the grids differ, and the fit says so).
COMMON_GRID_SHARE = 0.75


def _common_grid(datas):
    """``datas`` on the frequencies they all have, when their grids differ only by points
    some channels lack (a reader drops an analyser's zero or DC bins per channel) and
    those keep :data:`COMMON_GRID_SHARE` of the largest grid; else ``datas`` as given."""
    from ..core.data import FrequencyData
    from ..io.loaders import DataWarning

    if len({d.omega.tobytes() for d in datas}) < 2:
        return datas
    common = datas[0].omega
    for d in datas[1:]:
        common = np.intersect1d(common, d.omega)
    largest = max(d.n_points for d in datas)
    if common.size < max(2, COMMON_GRID_SHARE * largest):
        return datas
    cut = sorted({int(d.n_points - common.size) for d in datas if d.n_points > common.size})
    warnings.warn(f"the channels' grids differ only by points some channels lack (bins "
                  f"a reader dropped): kept the {common.size} frequencies all "
                  f"{len(datas)} channels share, dropping {cut[0]}..{cut[-1]} of a channel's "
                  "points", DataWarning, stacklevel=2)
    out = []
    for d in datas:
        keep = np.isin(d.omega, common)
        out.append(FrequencyData(d.omega[keep], d.response[keep], d.name,
                                 None if d.weights is None else d.weights[keep], d.unit))
    return out


def _channel_names(datas, files):
    """One name per channel, fit for a file name: the data's name (a UFF record's
    ``12+Z/1+Z`` as ``12+Z_1+Z``: the sign of a direction kept) or the file's stem, made
    unique by the channel's number."""
    names, seen = [], set()
    for k, (d, f) in enumerate(zip(datas, files)):
        base = d.name or os.path.splitext(os.path.basename(f))[0] or f"ch{k + 1}"
        base = re.sub(r"[^A-Za-z0-9_.=+-]+", "_", base).strip("._") or f"ch{k + 1}"
        name = base if base not in seen else f"{base}_{k + 1}"
        seen.add(name)
        names.append(name)
    return names


def _zeros(text, n):
    kinds = [t.strip() for t in str(text).split(",")]
    if len(kinds) == 1:
        kinds = kinds * n
    if len(kinds) != n or any(k not in ("minimum-phase", "free") for k in kinds):
        raise OptionError(f"--zeros must be free or minimum-phase, once or once per "
                          f"channel ({n}), got {text!r}")
    return kinds


def run_cli(args, command):
    """Run ``freqid modal`` for the parsed ``args``; return 0.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid modal`` arguments (``files``, ``orders``, ``out``, ``force``,
        ``delay``, ``zeros``, ``integrator``, ``freq_tol``, ``damping_tol``, ``min_stable``,
        ``max_iter`` (``--max-iter k``: ``method=IpoptOptions(max_iter=k,
        final_max_iter=2 k)``), ``channel_sections``, ``balance_channels``).
    command : str
        The command line, written as the first line of ``summary.md``.

    Raises
    ------
    FreqidError
        DataError for unreadable files or different grids, OptionError for bad options or
        an existing ``--out`` without ``--force``.
    """
    from .common import notes_to_stderr
    from ..modal.survey import parse_orders, stabilization
    from ..report.folder import check_out_dir, report_folder

    check_out_dir(args.out, args.force)
    orders = parse_orders(args.orders)
    with notes_to_stderr() as notes:         # the files' notes together, each text once
        channels = [(d, f) for f in args.files for d in _file_channels(args, f)]
        datas, files = _common_grid([d for d, _ in channels]), [f for _, f in channels]
    names = _channel_names(datas, files)
    delay = False if args.delay == "none" else args.delay
    if args.min_stable < 1 or args.max_iter < 1 or args.jobs < 1:
        raise OptionError(f"--min-stable, --max-iter and --jobs must be >= 1, got "
                          f"{args.min_stable}, {args.max_iter}, {args.jobs}")
    if args.channel_sections < 0:
        raise OptionError(f"--channel-sections must be >= 0, got {args.channel_sections}")
    coords = _coordinates(args.coordinates, len(datas))
    ref = _reference(args.reference_shapes, len(datas))
    res = stabilization(datas, orders, freq_tol=args.freq_tol, damping_tol=args.damping_tol,
                        min_stable=args.min_stable, delay=delay,
                        zeros=_zeros(args.zeros, len(datas)), integrator=args.integrator,
                        method=IpoptOptions(max_iter=args.max_iter,
                                            final_max_iter=2 * args.max_iter),
                        channel_sections=args.channel_sections,
                        balance_channels=args.balance_channels, estimator=args.estimator,
                        n_jobs=args.jobs)
    with report_folder(args.out, args.force) as (tmp, path):
        _write_report(res, tmp, names, command, coords, ref,
                      read=(notes, [(f, d.name) for d, f in zip(datas, files)]))
    print(f"{len(res.modes)} modes selected; report in {path}")
    if not res.modes:
        print(f"none: a mode is selected when it is stable in frequency and damping at each "
              f"of the last {args.min_stable} orders (--min-stable {args.min_stable}); "
              f"{res.selection_note or 'the highest order has no underdamped pole'}; "
              "stabilization.csv has every pole's status")
    return 0


def _write_shapes(res, folder, names, coords, ref):
    """shapes.csv, shape_<k>.png and (with ``ref``) mac.csv; returns (shapes, MAC or None)."""
    from ..core.modes import mac, mode_shapes, shapes_csv
    from ..plots import save_figure
    from ..plots.modal import mode_shape_figure

    shapes = mode_shapes(res.modes, coords, names)
    atomic_write_text(os.path.join(folder, "shapes.csv"), shapes_csv(shapes))
    for k in range(len(shapes)):
        save_figure(mode_shape_figure(shapes, k), os.path.join(folder, f"shape_{k + 1}.png"))
    if ref is None or not len(shapes):
        return shapes, None
    m = mac(shapes, ref)
    lines = ["mode,frequency_hz," + ",".join(f"ref{j + 1}" for j in range(ref.shape[0]))]
    lines += [f"{i + 1},{f!r}," + ",".join(repr(float(v)) for v in row)
              for i, (f, row) in enumerate(zip(shapes.frequency_hz, m))]
    atomic_write_text(os.path.join(folder, "mac.csv"), "\n".join(lines) + "\n")
    return shapes, m


def _write_report(res, folder, names, command, coords=None, ref=None, read=((), ())):
    """The report's files; ``read``: the reader's notes and each channel's (file, name in
    the file), for the section on how the data were read."""
    from ..core.modes import modes_csv, modes_markdown
    from ..modal.survey import stabilization_csv
    from ..plots import bode, save_figure
    from ..plots.modal import stabilization_diagram

    top, label = _model_fit(res)
    join = os.path.join
    atomic_write_text(join(folder, "modes.csv"), modes_csv(res.modes, names))
    atomic_write_text(join(folder, "modes.md"), modes_markdown(res.modes, names))
    atomic_write_text(join(folder, "stabilization.csv"), stabilization_csv(res))
    save_figure(stabilization_diagram(res), join(folder, "stabilization.png"))
    for name, data, model in zip(names, top.datas if top else (), top.models if top else ()):
        model.save(join(folder, f"model_{name}.json"))
        save_figure(bode(data, models={label: model},
                         title=f"{name}: data and shared-pole model"),
                    join(folder, f"bode_{name}.png"))
    shapes, m = _write_shapes(res, folder, names, coords, ref)
    summary = _summary(res, names, command)
    summary["selection_note"] = res.selection_note
    summary["read_notes"] = list(read[0])
    summary["sources"] = {n: {"file": str(f), "response": str(r or "")}
                          for n, (f, r) in zip(names, read[1])}
    summary["shapes"] = [{"frequency_hz": float(f), "mpc": float(p), "mpd_deg": float(d),
                          "real": bool(r), "shape": [float(v) for v in a.real]}
                         for f, p, d, r, a in zip(shapes.frequency_hz, shapes.mpc,
                                                  shapes.mpd_deg, shapes.is_real,
                                                  shapes.aligned)]
    if m is not None:
        summary["mac_vs_reference"] = m.tolist()
    atomic_write_text(join(folder, "summary.json"),
                      json.dumps(summary, indent=1, allow_nan=False) + "\n")
    atomic_write_text(join(folder, "summary.md"), _markdown(summary, res, names))


def _model_fit(res):
    """``(SharedFitResult or None, label)``: the fit whose models the report writes, the
    polish of the selected modes (the highest order's fit with ``--estimator full``)."""
    if res.polished is not None:
        return res.polished, f"{res.polished.n_shared} shared sections (selected modes)"
    if res.estimator == "full":
        return res.fits[-1], f"order {res.orders[-1]}"
    return None, ""


def _summary(res, names, command):
    from ..modal.shared import turns_phase

    top, label = _model_fit(res)
    return {
        "command": command, "orders": list(res.orders), "channels": names,
        "freq_tol": res.freq_tol, "damping_tol": res.damping_tol,
        "estimator": res.estimator,
        "options": dict((top or res.fits[-1]).options),
        "n_modes_selected": len(res.modes),
        "modes": [{"frequency_hz": m.frequency_hz, "omega_n": m.omega_n, "zeta": m.zeta}
                  for m in res.modes],
        "per_order": [{"order": o, "max_rel_error": float(np.max(f.max_rel_errors)),
                       "success": f.success, "message": f.message,
                       "wall_time": f.wall_time, "nit": f.nit}
                      for o, f in zip(res.orders, res.fits)],
        "model": label, "model_message": top.message if top else "",
        "top_order": None if top is None else {
                      "max_rel_errors": dict(zip(names, map(float, top.max_rel_errors))),
                      "rms_rel_errors": dict(zip(names, map(float, top.rms_rel_errors))),
                      "delays": dict(zip(names, map(float, top.delays))),
                      "minimum_phase": dict(zip(names, [m.is_minimum_phase()
                                                        for m in top.models])),
                      "rhp_zeros_in_band": dict(zip(names, [
                          turns_phase(m, d.omega) for m, d in zip(top.models, top.datas)])),
                      "channel_poles_omega_n": dict(zip(names, [
                          sorted(float(abs(p)) for p in ps if p.imag >= 0)
                          for ps in top.channel_poles])),
                      "single_max_rel_errors": dict(zip(names, map(
                          float, top.single_max_rel_errors)))},
    }


def _own_line(options):
    k = options.get("channel_sections", 0)
    text = (f"Each channel also has {k} section(s) of its own (poles not modes, not in the "
            f"order), standing in for the modes outside the band." if k else "")
    if options.get("balance_channels"):
        text += (" Channels reweighted so that none has a larger max rel. error than its own "
                 "single-channel fit.")
    return text.strip()


def _markdown(s, res, names):
    from ..core.modes import modes_markdown

    lines = [f"`{s['command']}`", "", "# Modal analysis: shared poles", "",
             f"{len(names)} channels, orders {s['orders'][0]}..{s['orders'][-1]}; a pole is "
             f"stable when the previous order has one within {100 * s['freq_tol']:g} % in "
             f"frequency (and {100 * s['damping_tol']:g} % in damping); "
             f"{s['n_modes_selected']} modes selected.", _own_line(s["options"]), "",
             "## Selected modes", "",
             modes_markdown(res.modes, names)]
    if s.get("selection_note"):
        lines += [f"Not selected: {s['selection_note']}.", ""]
    each = ("shared-pole vector fitting" if s["estimator"] == "rational"
            else "shared-pole fit")
    lines += [f"## Each order ({each})", "",
             "| order | worst max rel. error | converged | iterations | time (s) |",
             "|---:|---:|---|---:|---:|"]
    lines += [f"| {r['order']} | {r['max_rel_error']:.3g} | {'yes' if r['success'] else 'no'} "
              f"| {r['nit']} | {r['wall_time']:.2f} |" for r in s["per_order"]]
    t = s["top_order"]
    if t is None:
        lines += ["", "No model: no mode was selected (model files and Bode plots are "
                  "written for the fit of the selected modes).", ""]
        lines += _shape_lines(s, names)
        lines += _read_lines(s, names)
        return "\n".join(lines) + "\n"
    lines += ["", f"## Channels, model of {s['model']}", "",
              f"How the fit ended: {modal_words(s['model_message'])}", "",
              "| channel | max rel. error | RMS rel. error | delay (s) | minimum phase | "
              "right-half-plane zeros in the band |",
              "|---|---:|---:|---:|---|---|"]
    lines += [f"| {n} | {t['max_rel_errors'][n]:.3g} | {t['rms_rel_errors'][n]:.3g} | "
              f"{t['delays'][n]:.6g} | {'yes' if t['minimum_phase'][n] else 'no'} | "
              f"{_in_band(t, n)} |" for n in names]
    lines += _shape_lines(s, names)
    lines += _read_lines(s, names)
    lines += ["", "Files: modes.csv/.md, shapes.csv, shape_<k>.png, stabilization.csv/.png, "
              "bode_<channel>.png, model_<channel>.json, summary.json"
              + (", mac.csv." if "mac_vs_reference" in s else ".")]
    return "\n".join(lines) + "\n"


def _read_lines(s, names):
    """Where each channel came from (its file and the response's name in it) and the
    readers' notes."""
    sources = s.get("sources") or {}
    if not sources:
        return []
    lines = ["", "## How the data were read", "", "| channel | file | response |",
             "|---|---|---|"]
    lines += [f"| {md_cell(n)} | {md_cell(sources[n]['file'])} | "
              f"{md_cell(sources[n]['response'])} |" for n in names if n in sources]
    if s.get("read_notes"):
        lines += [""] + [f"- {md_text(t)}" for t in s["read_notes"]]
    return lines


def modal_words(text):
    """``text`` (a shared fit's message) with its advice in this command's words:
    ``n_sections=5 or more`` as ``--orders reaching 10 or more``, ``channel_sections=2`` as
    ``--channel-sections 2``, ``zeros='free'`` as ``--zeros free``.

    Parameters
    ----------
    text : str

    Returns
    -------
    str
    """
    from .common import cli_words

    text = re.sub(r"n_sections=(\d+) or more",
                  lambda m: f"--orders reaching {2 * int(m.group(1))} or more", text)
    text = re.sub(r"channel_sections=(\d+)", r"--channel-sections \1", text)
    return cli_words(text.replace(" (freqid modal --zeros free)", ""))


def _in_band(t, name):
    """The summary's cell: whether a channel's right-half-plane zeros turn its phase in
    the band (absent in a summary.json written before they were recorded)."""
    value = t.get("rhp_zeros_in_band", {}).get(name)
    return "" if value is None else ("yes" if value else "no")


def _shape_lines(s, names):
    """The summary's mode-shape table (and the MAC against the reference shapes)."""
    if not s["shapes"]:
        return []
    out = ["", "## Mode shapes", "",
           "Modal constants rotated by each mode's principal phase, largest component +1 "
           "(real part shown); MPC 1 and MPD 0 deg for a real (normal) mode.", "",
           "| mode | f (Hz) | MPC | MPD (deg) | " + " | ".join(names) + " |",
           "|---:|---:|---:|---:|" + "---:|" * len(names)]
    for i, sh in enumerate(s["shapes"], 1):
        out.append(f"| {i} | {sh['frequency_hz']:.6g} | {sh['mpc']:.4f} | "
                   f"{sh['mpd_deg']:.2f} | " + " | ".join(f"{v:.3f}" for v in sh["shape"])
                   + " |")
    if "mac_vs_reference" in s:
        m = s["mac_vs_reference"]
        out += ["", "MAC against the reference shapes (rows: selected modes, columns: "
                "reference modes):", "",
                "| mode | " + " | ".join(f"ref {j + 1}" for j in range(len(m[0]))) + " |",
                "|---:|" + "---:|" * len(m[0])]
        out += [f"| {i} | " + " | ".join(f"{v:.3f}" for v in row) + " |"
                for i, row in enumerate(m, 1)]
    return out

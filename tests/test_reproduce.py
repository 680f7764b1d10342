"""The thesis-reproduction study (freqid_casadi.studies.reproduce, its report and
`freqid reproduce`) in quick mode (about a minute)."""

import json
import runpy
from pathlib import Path

import pytest

from freqid_casadi.cli import app as cli
from freqid_casadi.errors import OptionError
from freqid_casadi.report.formatting import generated_by_line, number as table_cell
from freqid_casadi.studies.reproduce import EXAMPLE_NAMES, TABLE_QUANTITIES
from freqid_casadi.studies.reproduce_report import TABLE_COLUMNS
from freqid_casadi.studies.reproduce_report import write_reproduce_report as reproduce

COMMAND = "python scripts/reproduce_thesis.py --quick --out OUT"


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("repro") / "thesis"
    summary = reproduce(out, command=COMMAND, quick=True)
    return out, summary


def _markdown_table(lines, header_start):
    """Rows (lists of cells) of the Markdown table whose header starts with header_start."""
    i = next(k for k, line in enumerate(lines) if line.startswith(header_start))
    rows = []
    for line in lines[i + 2:]:
        if not line.startswith("|"):
            break
        rows.append([c.strip().replace("\\|", "|") for c in line.strip().strip("|").split(" | ")])
    return lines[i], rows


def test_quick_report_files_and_first_line(quick_report):
    out, summary = quick_report
    files = {p.name for p in out.iterdir()} - {".freqid-output"}   # the package's marker
    assert {"report.md", "report.json", "curves.json", "A_model.json"} <= files
    for name in ("A_bode.png", "A_rel_error.png", "A_pole_zero.png", "A_hsv.png",
                 "A_methods.png", "A_perturbed.png", "fractional_bode.png",
                 "fractional_closed_loop_error.png", "moheimani_bode.png",
                 "moheimani_error.png"):
        assert name in files
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(summary["files"]) == files
    text = (out / "report.md").read_text(encoding="utf-8")
    assert text.splitlines()[0] == generated_by_line(COMMAND)
    assert json.loads((out / "report.json").read_text()) == summary
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".thesis.")]


def test_table_in_markdown_equals_json(quick_report):
    out, summary = quick_report
    table = summary["table_4_1"]
    assert table["columns"] == list(TABLE_COLUMNS)
    lines = (out / "report.md").read_text(encoding="utf-8").splitlines()
    header, rows = _markdown_table(lines, "| example | quantity |")
    assert header.split(" | ")[2:][-1].rstrip(" |") == TABLE_COLUMNS[-1]
    assert len(rows) == len(table["rows"]) == len(TABLE_QUANTITIES)
    labels = dict(TABLE_QUANTITIES)
    for md, js in zip(rows, table["rows"]):
        assert md[0] == js["example"] and md[1] == labels[js["quantity"]]
        assert len(md) == 2 + len(js["values"])
        for cell, value in zip(md[2:], js["values"]):
            assert cell == table_cell(value)
            if isinstance(value, float):
                assert float(cell) == pytest.approx(value, rel=5e-4)
    # the numbers of our IPOPT fit are the model's
    ours = summary["examples"]["A"]["methods"]["ipopt"]
    assert ours["n_rhp_zeros"] == 0 and ours["minimum_phase"] is True
    row = next(r for r in table["rows"] if r["quantity"] == "max_rel_error")
    assert row["values"][TABLE_COLUMNS.index("ours (IPOPT)")] == ours["max_rel_error"]
    assert row["values"][TABLE_COLUMNS.index("thesis subspace")] == 2.5724


def test_subspace_table_and_fractional_in_markdown(quick_report):
    out, summary = quick_report
    lines = (out / "report.md").read_text(encoding="utf-8").splitlines()
    _, rows = _markdown_table(lines, "| example | thesis subspace")
    assert rows == [["A", "2.572",
                     table_cell(summary["examples"]["A"]["methods"]["subspace"]
                                ["max_rel_error"]),
                     table_cell(summary["examples"]["A"]["methods"]["subspace"]["n_poles"])]]
    _, rows = _markdown_table(lines, "| method | poles | max E")
    methods = summary["fractional"]["methods"]
    assert [r[0] for r in rows] == list(methods)
    for r in rows:
        assert r[2] == table_cell(methods[r[0]]["max_closed_loop_error"])
    k = summary["moheimani"]
    assert k["max_abs_error_in_band_with_k"] < k["max_abs_error_in_band_without_k"]
    assert k["k_from_data"] == pytest.approx(k["k_opt"], rel=1e-6)


def test_refuses_existing_folder_without_force(tmp_path):
    out = tmp_path / "thesis"
    out.mkdir()
    with pytest.raises(OptionError, match="exists; pass --force"):
        reproduce(out, command="x", quick=True)
    with pytest.raises(OptionError, match="examples must be"):
        reproduce(tmp_path / "new", command="x", quick=True, examples="A,Z")
    assert not (tmp_path / "new").exists()


def test_cli_parser():
    args = cli.build_parser().parse_args(["reproduce", "--quick", "--examples", "A,B"])
    assert args.out.endswith("thesis") and args.quick and not args.force
    assert args.examples == "A,B"
    assert set(EXAMPLE_NAMES) == {"A", "B", "C", "fractional", "moheimani"}


def test_time_limited_fit_stops_and_reports_last_stage():
    from freqid_casadi import systems
    from freqid_casadi.studies.reproduce import _fit_time_limited

    data = systems.G_A().window(60)
    res, elapsed, last = _fit_time_limited(data, 0.0, n_sections=2, integrator=True,
                                           method="barrier-lm")
    assert res is None and last.stage == 0 and elapsed >= 0
    res, _, last = _fit_time_limited(data, 1e6, n_sections=1, integrator=True,
                                     method="ipopt")
    assert last is None and res.model.n_sections == 1


def test_script_calls_the_cli_with_its_own_command(monkeypatch):
    seen = []
    monkeypatch.setattr(cli, "main", lambda argv: seen.append(argv) or 0)
    script = Path(__file__).resolve().parents[1] / "scripts" / "reproduce_thesis.py"
    assert runpy.run_path(str(script))["main"](["--quick", "--out", "my dir"]) == 0
    assert seen == [["reproduce", "--quick", "--out", "my dir", "--progress",
                     "--report-command",
                     "python scripts/reproduce_thesis.py --quick --out 'my dir'"]]

"""Names of the records of a universal file (dataset 58): in a file of several FRFs, each is
named by its response and reference node and direction (``12+Z/1+Z``), as modal-testing
tools label an FRF; a header without nodes keeps the first ID line or ``<stem>:<k>``.

Each file is written by the test byte for byte in the layout of dataset 58 (ASCII): record
6 holds the function type, the response entity, node and direction, then the reference's.
"""

import json
import os
import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.cli.app import main
from freqid_casadi.io.loaders import DataWarning, load_uff

pytest.importorskip("pyuff")


def _record(ident, rsp_node, rsp_dir, ref_node, ref_dir, values, freqs=(1.0, 2.0, 4.0)):
    """One dataset-58 record: an FRF (type 4) of complex ordinates (double precision,
    uneven abscissa) at ``freqs`` Hz."""
    rows = "".join(f"  {f:.5E}  {z.real:18.11E}  {z.imag:18.11E}\n"
                   for f, z in zip(freqs, values))
    return ("    -1\n    58\n"
            f"{ident}\nNONE\nNONE\nNONE\nNONE\n"
            f"    4         1    1         0       NONE{rsp_node:10d}{rsp_dir:4d}"
            f"       NONE{ref_node:10d}{ref_dir:4d}\n"
            f"         6{len(freqs):10d}         0  0.00000E+00  0.00000E+00  0.00000E+00\n"
            "        18    0    0    0 Frequency            Hz\n"
            "        12    0    0    0 Acceleration         m/s^2\n"
            "        13    0    0    0 Force                N\n"
            "         0    0    0    0 NONE                 NONE\n"
            f"{rows}    -1\n")


H = np.array([2 - 1j, 1 - 0.5j, 0.25 + 0.5j])


def _file(tmp_path, name, *records):
    path = tmp_path / name
    path.write_bytes("".join(_record(*r) for r in records).encode("ascii"))
    return path


def test_records_are_named_by_node_and_direction(tmp_path):
    # a roving-hammer test: response nodes 12 (+Z) and 7 (-Y), reference node 1 (+Z); the
    # ID lines are the analyser's one title for every record, which named none apart
    path = _file(tmp_path, "impact.unv", ("Trace title", 12, 3, 1, 3, H),
                 ("Trace title", 7, -2, 1, 3, 2 * H), ("NONE", 5, 6, 0, 0, 3 * H))
    datas = load_uff(path)
    assert [d.name for d in datas] == ["12+Z/1+Z", "7-Y/1+Z", "5+RZ"]
    np.testing.assert_array_equal(datas[1].response, 2 * H)
    np.testing.assert_allclose(datas[1].omega, 2 * np.pi * np.array([1.0, 2.0, 4.0]),
                               rtol=1e-15)
    # fc.load of one record names it as load_uff does
    one = fc.load(path, record=1)
    assert one.name == "7-Y/1+Z"
    np.testing.assert_array_equal(one.response, [4 - 2j, 2 - 1j, 0.5 + 1j])


def test_records_each_with_its_own_id_line_keep_the_users_labels(tmp_path):
    # the ID lines name every record apart: they are the user's labels, kept (as before
    # node names were read); one shared or missing ID line and the nodes name them all
    path = _file(tmp_path, "labelled.unv", ("tip accel", 12, 3, 1, 3, H),
                 ("root accel", 7, -2, 1, 3, 2 * H))
    assert [d.name for d in load_uff(path)] == ["tip accel", "root accel"]
    path = _file(tmp_path, "half.unv", ("tip accel", 12, 3, 1, 3, H),
                 ("NONE", 7, -2, 1, 3, 2 * H))
    assert [d.name for d in load_uff(path)] == ["12+Z/1+Z", "7-Y/1+Z"]


def test_a_pair_measured_twice_gets_its_record_number(tmp_path):
    path = _file(tmp_path, "twice.unv", ("H", 3, 1, 1, 1, H), ("H", 3, 1, 1, 1, 2 * H),
                 ("H", 4, 1, 1, 1, H))
    assert [d.name for d in load_uff(path)] == ["3+X/1+X:0", "3+X/1+X:1", "4+X/1+X"]


def test_a_header_without_nodes_keeps_the_id_line_or_the_record_number(tmp_path):
    path = _file(tmp_path, "plain.unv", ("left mic", 0, 0, 0, 0, H),
                 ("NONE", 0, 1, 0, 0, 2 * H))
    assert [d.name for d in load_uff(path)] == ["left mic", "plain:1"]
    # a file of one record keeps its ID line (no other record to tell it from)
    single = _file(tmp_path, "single.unv", ("hand-written FRF", 12, 3, 1, 3, H))
    assert fc.load(single).name == "hand-written FRF"


def test_cli_modal_names_each_channel_by_its_nodes(tmp_path, capsys):
    # two records of a two-mode structure; the report's files carry the nodes, the sign of
    # the direction kept ('7-Y/1+Z' is written 7-Y_1+Z)
    f = np.round(np.linspace(0.5, 4.0, 60), 4)         # stored exactly by %13.5e
    s = 2j * np.pi * f

    def frf(k):
        return k / (s ** 2 + 0.2 * s + 40.0) + 1.0 / (s ** 2 + 0.3 * s + 300.0)

    path = _file(tmp_path, "modal.unv", ("T", 12, 3, 1, 3, frf(1.0), f),
                 ("T", 7, -2, 1, 3, frf(-2.0), f))
    out = tmp_path / "rep"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        assert main(["modal", str(path), "--orders", "4:8:2", "--min-stable", "2",
                     "--out", str(out), "--zeros", "free"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["channels"] == ["12+Z_1+Z", "7-Y_1+Z"]
    assert {"bode_12+Z_1+Z.png", "bode_7-Y_1+Z.png"} <= set(os.listdir(out))

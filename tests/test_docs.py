"""The documentation stays true: the user guide's code runs (doctest), every public name is
in the API reference, and the Sphinx site builds with warnings as errors (the gallery runs
every example and draws its figures)."""

import doctest
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import freqid_casadi as fc

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^\s*(```|~~~|:::).*$", re.MULTILINE)


def _pages_with_examples():
    pages = sorted(DOCS.glob("*.md")) + sorted((DOCS / "guide").glob("*.md"))
    return [p for p in pages if ">>> " in p.read_text(encoding="utf-8")]


@pytest.mark.parametrize("page", _pages_with_examples(), ids=lambda p: p.name)
def test_guide_code_runs(page):
    """Every ``>>>`` example of a docs page gives the output printed under it (code fences
    are blanked first, so a closing fence does not count as expected output)."""
    text = FENCE.sub("", page.read_text(encoding="utf-8"))
    parser = doctest.DocTestParser()
    test = parser.get_doctest(text, {"__name__": "__docs__"}, page.name, str(page), 0)
    assert test.examples, f"{page.name}: no examples parsed"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    res = runner.summarize(verbose=False)
    assert res.failed == 0, f"{page.name}: {res.failed} of {res.attempted} examples failed"


def _autosummary_names(rst):
    """Names listed in the autosummary directives of an .rst file."""
    names, inside = [], False
    for line in rst.splitlines():
        if line.startswith(".. autosummary::"):
            inside = True
            continue
        if inside:
            if line.strip().startswith(":") or not line.strip():
                continue
            if line.startswith("   "):
                names.append(line.strip())
            else:
                inside = False
    return names


def test_every_public_name_is_listed_in_the_api_reference():
    listed = set(_autosummary_names((DOCS / "api" / "index.rst").read_text(encoding="utf-8")))
    subpackages = _autosummary_names((DOCS / "api" / "subpackages.rst").read_text(encoding="utf-8"))
    missing = [n for n in fc.__all__ if n not in listed and f"freqid_casadi.{n}" not in subpackages]
    assert not missing, f"docs/api/index.rst lacks {missing} (names of freqid_casadi.__all__)"
    for pkg in ("core", "io", "experiment", "systems", "solvers", "uncertainty", "fitting",
                "modal", "plots", "baselines"):
        assert f"freqid_casadi.{pkg}" in subpackages, f"docs/api/subpackages.rst lacks {pkg}"


NEEDED = ("sphinx", "numpydoc", "sphinx_gallery", "pydata_sphinx_theme", "myst_parser")


@pytest.mark.slow
@pytest.mark.skipif(any(importlib.util.find_spec(m) is None for m in NEEDED),
                    reason="the docs extra is not installed: pip install -e '.[docs]'")
def test_sphinx_build_warnings_are_errors(tmp_path):
    """``python -m sphinx -W -b html docs OUT`` passes; every name of ``fc.__all__`` has its
    page in the API reference and every gallery example drew at least one figure."""
    out = tmp_path / "html"
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT) + os.pathsep
               + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b",
                           "html", "-d", str(tmp_path / "doctrees"), str(DOCS), str(out)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, f"sphinx -W failed:\n{proc.stderr[-6000:]}"
    api = (out / "api" / "index.html").read_text(encoding="utf-8")
    for name in fc.__all__:
        page = out / "generated" / f"freqid_casadi.{name}.html"
        assert page.is_file(), f"no API page for fc.{name}"
        assert f"generated/freqid_casadi.{name}.html" in api, f"fc.{name} not linked"
    examples = sorted(p.stem for p in (DOCS / "examples").glob("plot_*.py"))
    assert len(examples) >= 10
    images = {p.name for p in (out / "_images").glob("sphx_glr_*.png")}
    for ex in examples:
        assert any(i.startswith(f"sphx_glr_{ex}_0") for i in images), f"{ex} drew no figure"


def test_readme_is_a_front_door_with_the_ci_command():
    """README.md: at most 150 lines, starting with the install command and then the test
    command, which is exactly the command .ci/run runs."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 150
    blocks = re.findall(r"```bash\n(.*?)\n```", readme, flags=re.DOTALL)
    assert blocks[0] == ("python3 -m venv .venv && .venv/bin/pip install -q -e . && "
                         ".venv/bin/freqid example A")
    ci = [ln for ln in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
          if ln.startswith("python3 -m venv")]
    assert ci == [blocks[1]], "README's test command and .ci/run differ"
    assert "'.[test,docs]'" in blocks[1]
    assert "<!-- layer map: read by tests/test_layout.py -->" in readme

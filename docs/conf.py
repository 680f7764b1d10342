"""Sphinx configuration of the freqid_casadi documentation.

Build: ``python -m sphinx -W -b html docs docs/_build/html`` (warnings are errors; the
build output and the generated pages -- ``_build``, ``generated``, ``auto_examples`` -- are
git-ignored). The gallery runs every ``docs/examples/*.py`` at build time.
"""

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # the checkout, before any installed copy

os.environ.setdefault("MPLBACKEND", "Agg")


def _short_warning(message, category, filename, lineno, line=None):
    """The gallery shows warnings the package gives as one line, without the build's paths."""
    return f"{category.__name__}: {message}\n"


import warnings  # noqa: E402

warnings.formatwarning = _short_warning

import freqid_casadi  # noqa: E402

project = "freqid_casadi"
author = "the freqid_casadi authors"
copyright = "the freqid_casadi authors, BSD-3-Clause"
release = getattr(freqid_casadi, "__version__", "0.1.0")
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.doctest",
    "sphinx.ext.mathjax",
    "sphinx.ext.intersphinx",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "**.ipynb_checkpoints", "examples/README.rst",
                    "examples/GALLERY_HEADER.rst"]
templates_path = ["_templates"]

# -- MyST (Markdown pages: docs/guide/*.md, spec.md, style.md, ...) ---------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
# spec.md and the guide pages link to files of the repository (../scripts/x.py) that are
# not documents of the site; those are plain links, not cross-reference failures.
suppress_warnings = ["myst.xref_missing", "myst.header"]

# -- autodoc / autosummary / numpydoc ---------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()
numpydoc_xref_param_type = False

intersphinx_mapping = {}  # offline build: no inventories fetched

# -- doctest (the user guide's code blocks marked as doctest) ---------------------------
doctest_global_setup = """
import numpy as np
import freqid_casadi as fc
"""

# -- sphinx-gallery ---------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"__init__\.py|/_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "matplotlib_animations": False,
    "reset_modules": ("matplotlib",),
    "min_reported_time": 1,
    # every build runs every example, so the gallery shows what the code does now, not what
    # it did when the example last changed
    "run_stale_examples": True,
    # show what the examples print, not the repr of a figure returned by their last line
    "capture_repr": (),
}

# -- HTML -------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = "freqid_casadi"
html_static_path = ["_static"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_show_sourcelink = False


# -- |x| in docstrings ------------------------------------------------------------------
# Docstrings write absolute values as |x| (``|(Phi - G_N)/G_N|``), which reStructuredText
# reads as a substitution reference. Escape such bars in prose lines before numpydoc parses
# the docstring; literal blocks (after ``::``), doctest blocks, inline literals and table or
# line-block lines (starting with "| ", "+-" or "+=") are left alone.
import re  # noqa: E402

_LITERAL = re.compile(r"(``.*?``|`[^`]*`)")


def _escape_bars(line):
    parts = _LITERAL.split(line)
    return "".join(p if i % 2 else re.sub(r"(?<!\\)\|", r"\\|", p) for i, p in enumerate(parts))


def _escape_abs_bars(app, what, name, obj, options, lines):
    literal_indent, in_doctest, prev = None, False, ""
    for i, line in enumerate(lines):
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None:
            if stripped and indent <= literal_indent:
                literal_indent = None
            else:
                continue
        if in_doctest:
            in_doctest = bool(stripped)
            continue
        if stripped.startswith(">>>"):
            in_doctest = True
            continue
        if "|" in line and not (stripped == "|" or stripped.startswith(("| ", "+-", "+="))):
            lines[i] = _escape_bars(line)
        if stripped.endswith("::"):
            literal_indent = indent
        prev = line
    return prev


def setup(app):
    app.connect("autodoc-process-docstring", _escape_abs_bars, priority=100)

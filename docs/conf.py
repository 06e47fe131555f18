"""Sphinx configuration of the lunarviz documentation (built with ``sphinx-build -W``)."""

import os
import sys

sys.path.insert(0, os.path.abspath(".."))

project = "lunarviz"
author = "the lunarviz developers"
copyright = "lunarviz developers, MIT licence"  # noqa: A001 (Sphinx's name)
from lunarviz import __version__ as release  # noqa: E402

version = release

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
exclude_patterns = ["_build"]
autosummary_generate = True
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_validation_checks: set = set()
# third-party types in signatures and docstrings are not cross-referenced (no network at build time)
nitpicky = False
suppress_warnings = ["myst.xref_missing", "myst.header"]
html_theme = "alabaster"
html_title = f"lunarviz {release}"


def _write_options_table() -> None:
    """docs/_generated/options_table.md from the option schema (lunarviz.options)."""
    from lunarviz.options import GROUPS, group

    out = ["| keyword | flag | default | unit | group | meaning |", "| --- | --- | --- | --- | --- | --- |"]
    for g in GROUPS:
        for o in group(g):
            allowed = f" One of: {', '.join(o.choices)}." if o.choices and o.kind == "str" else ""
            doc = (o.doc + "." + allowed).replace("|", "\\|")
            out.append(f"| `{o.name}` | `{o.cli_flag}` | `{o.default!r}` | {o.unit or ''} | {o.group} | {doc} |")
    folder = os.path.join(os.path.dirname(__file__), "_generated")
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "options_table.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")


_write_options_table()
exclude_patterns += ["_generated"]

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
    "myst_nb",  # (MyST Markdown, and the example notebook executed at each build)
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
# the example notebook runs at every build (at smoke size, its 3D view as a static picture): the
# pages show its outputs as this version computes them
nb_execution_mode = "force"
nb_execution_timeout = 300
nb_execution_raise_on_error = True
nb_output_stderr = "remove"  # (a headless VTK's display warnings are not the notebook's output)
os.environ.setdefault("LUNARVIZ_SMOKE", "1")
os.environ.setdefault("LUNARVIZ_JUPYTER_BACKEND", "static")
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
# a page as wide as the window (alabaster's 940 px cut code blocks and the options table at 1280 px)
html_theme_options = {"page_width": "95%", "body_max_width": "none"}
html_static_path = ["_static"]
html_css_files = ["wrap.css"]
# "--flag" stays two hyphens (docutils' smart quotes made it an en dash: "–executor dask")
smartquotes = False

# "(paper Eq. 12)" does not end a module's one-line summary in the API tables
import sphinx.ext.autosummary as _autosummary  # noqa: E402

_autosummary.WELL_KNOWN_ABBREVIATIONS = (*_autosummary.WELL_KNOWN_ABBREVIATIONS, "Eq.", "Eqs.", "Fig.", "Figs.",
                                         "Sec.", "Secs.", "cf.", "No.", "approx.")


def _unlink_placeholders(app, doctree) -> None:
    """Metavariables that docutils reads as addresses (``FILE:MEAN``: a "file:" URI,
    ``tcp://host:8786``) stay text, not broken links."""
    from docutils import nodes
    for ref in list(doctree.findall(nodes.reference)):
        uri = ref.get("refuri", "")
        if uri == ref.astext() and (uri.split(":", 1)[0].isupper() or uri.startswith("tcp://host")):
            ref.replace_self(nodes.Text(ref.astext()))


def setup(app):
    app.connect("doctree-read", _unlink_placeholders)


def _write_options_table() -> None:
    """docs/_generated/options_table.md from the option schema (lunarviz.options): a table per group."""
    from lunarviz.options import GROUPS, group

    out = []
    for g in GROUPS:
        out += [f"### {g}", "", "| keyword (flag) | default | unit | meaning |", "| --- | --- | --- | --- |"]
        for o in group(g):
            allowed = f" One of: {', '.join(o.choices)}." if o.choices and o.kind == "str" else ""
            doc = (o.doc + "." + allowed).replace("|", "\\|")
            out.append(f"| `{o.name}` (`{o.cli_flag}`) | `{o.default!r}` | {o.unit or ''} | {doc} |")
        out.append("")
    folder = os.path.join(os.path.dirname(__file__), "_generated")
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "options_table.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")


_write_options_table()


def _copy_notebook() -> None:
    """docs/notebook/lunarviz_tour.ipynb: the example notebook, copied in to be executed here."""
    import shutil
    here = os.path.dirname(__file__)
    os.makedirs(os.path.join(here, "notebook"), exist_ok=True)
    shutil.copy(os.path.join(here, "..", "examples", "lunarviz_tour.ipynb"), os.path.join(here, "notebook"))


_copy_notebook()
exclude_patterns += ["_generated"]

"""The README's and the documentation's code blocks, run verbatim (as skyfield doctests its docs).

Convention: a fenced ```` ```python ```` or ```` ```bash ```` block is run, as written, in a fresh
folder, and must end (exit 0) within its time limit; a ```` ```console ```` block is a command
shown, not run here: the set-up commands (CI runs them itself, ``.ci/run``), the documentation
build (CI again) and sketches that need what a test machine lacks (a Dask cluster on several
hosts, a TLE file of the user's). Nothing here may open a window or serve forever: pictures go
to files, viewers are left as comments.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: every block must finish within this [s]: the longest (README's Python) takes ~40 s here
TIMEOUT_S = 600


def _blocks():
    docs = ROOT / "docs"
    files = [ROOT / "README.md"] + sorted(p for p in docs.rglob("*.md")
                                          if not any(part.startswith("_") for part in p.relative_to(docs).parts))
    out = []
    for f in files:
        for i, m in enumerate(re.finditer(r"^```(python|bash)\n(.*?)^```$", f.read_text(encoding="utf-8"),
                                          flags=re.S | re.M)):
            out.append(pytest.param(m.group(1), m.group(2), id=f"{f.relative_to(ROOT)}:{i}"))
    return out


BLOCKS = _blocks()


def test_the_readme_has_runnable_blocks():
    ids = [p.id for p in BLOCKS]
    assert sum(i.startswith("README.md") for i in ids) >= 2  # the quick start's shell and Python


@pytest.mark.slow
@pytest.mark.parametrize("lang,code", BLOCKS)
def test_block_runs_verbatim(lang, code, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PATH"] = os.path.dirname(sys.executable) + os.pathsep + env.get("PATH", "")  # the `lunarviz` script
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    if lang == "python":
        argv = [sys.executable, "-c", code]
    else:
        argv = ["bash", "-e", "-o", "pipefail", "-c", code]
    r = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=TIMEOUT_S,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 0, f"{lang} block failed:\n{code}\n--- stderr ---\n{r.stderr[-3000:]}"

"""The package's layout rules, read from its source with Python's ``ast``.

* every package imports only packages of lower layers (the table of docs/architecture.md, read
  here), function-level imports included;
* nothing below the scene layer takes the resolved scene: no call of its input methods, no
  unannotated ``settings`` parameter;
* no import cycle between lunarviz's modules, function-level imports included (an import of
  ``pkg.mod`` counts as an edge to ``pkg.mod``; of a name from a module, to that module);
* no private name (one leading underscore) imported from another module;
* no function or method longer than 100 lines;
* an option is declared once: ``cloud_albedo`` (a scene option, as the example) appears in at
  most 3 modules;
* README.md is at most 200 lines.

Each check reports what breaks it, so a failure says where to look.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "lunarviz"
#: the longest function the house allows [lines]
MAX_FUNCTION_LINES = 100


def _modules() -> dict[str, Path]:
    mods = {}
    for p in PKG.rglob("*.py"):
        parts = list(p.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = p
    return mods


MODULES = _modules()


def _import_targets(mod: str, node, is_package: bool):
    """(target module, imported name or None) for each name an import statement brings."""
    if isinstance(node, ast.Import):
        return [(a.name, None) for a in node.names]
    base = mod.split(".") if is_package else mod.split(".")[:-1]
    if node.level:
        base = base[:len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    out = []
    for a in node.names:
        full = f"{target}.{a.name}"
        out.append((full, None) if full in MODULES else (target, a.name))
    return out


def _graph():
    edges: dict[str, set] = {m: set() for m in MODULES}
    private = []
    for mod, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for target, name in _import_targets(mod, node, path.name == "__init__.py"):
                if not (target == "lunarviz" or target.startswith("lunarviz.")):
                    continue
                while target not in MODULES and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target != mod:
                    edges[mod].add(target)
                    if name and name.startswith("_") and not name.startswith("__"):
                        private.append(f"{mod} imports {name} from {target}")
    return edges, private


def _cycles(edges) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def _layers() -> dict[str, int]:
    """``{package: layer}`` from the table under "## Layers" of docs/architecture.md."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    section = text.split("## Layers", 1)[1].split("\n## ", 1)[0]
    out = {}
    for m in re.finditer(r"^\| (\d+) \| ([^|]+)\|", section, flags=re.M):
        for name in re.findall(r"`([\w.]+)`", m.group(2)):
            out[name] = int(m.group(1))
    return out


LAYERS = _layers()


def _package(mod: str) -> str:
    """The layer table's name for a module: its package below ``lunarviz``, or the top-level
    module itself (``lunarviz`` for the package's ``__init__``)."""
    parts = mod.split(".")
    return "lunarviz" if len(parts) == 1 else parts[1]


def _upward(edges: dict, layers: dict) -> list[str]:
    """Imports from a package to one of its own layer or above (its own modules excepted)."""
    bad = []
    for mod, targets in edges.items():
        a = _package(mod)
        for t in targets:
            b = _package(t)
            if a != b and layers[b] >= layers[a]:
                bad.append(f"{mod} (layer {layers[a]}) imports {t} (layer {layers[b]})")
    return sorted(bad)


def test_the_layer_table_is_read_and_covers_every_package():
    assert LAYERS["constants"] == 0 and LAYERS["cli"] > LAYERS["api"] > LAYERS["workflows"] > LAYERS["scene"]
    assert sorted({_package(m) for m in MODULES} - set(LAYERS)) == []


def test_the_layer_checker_finds_an_upward_import():
    """The checker itself, on a graph with one import that goes up and one that goes down."""
    edges = {"lunarviz.methods.camera": {"lunarviz.scene.inputs", "lunarviz.geometry.scene_geometry"}}
    assert _upward(edges, LAYERS) == ["lunarviz.methods.camera (layer 8) imports lunarviz.scene.inputs (layer 10)"]


def test_packages_import_only_lower_layers():
    edges, _ = _graph()
    assert _upward(edges, LAYERS) == []


#: the resolved scene's input methods (lunarviz.scene.inputs, lunarviz.scene.tolerance): called only
#: at its layer and above, which hand the layers below their typed inputs
SCENE_INPUTS = ("brdf_models", "spectral_request", "spectral_inputs", "earth_model", "surfaces", "mapped_moon",
                "analytic_settings", "point_calibration_settings", "reference_settings", "trace_settings",
                "observer_model", "task", "geometry",
                "trace_plan", "reference_orders", "modelled", "warn_unmet_tolerance")


def _scene_uses(tree) -> list[str]:
    """Calls of the resolved scene's input methods, and ``settings`` parameters without a type."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in SCENE_INPUTS:
            out.append(f"line {node.lineno}: .{node.func.attr}()")
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for a in node.args.args + node.args.kwonlyargs:
                if a.arg == "settings" and (a.annotation is None or "ResolvedScene" in ast.unparse(a.annotation)):
                    out.append(f"line {node.lineno}: {node.name}(settings) without its own type")
    return out


def test_the_scene_checker_finds_a_resolved_scene_below_its_layer():
    code = "def synthesize(settings, key):\n    return settings.trace_settings().sun_order\n"
    assert sorted(_scene_uses(ast.parse(code))) == ["line 1: synthesize(settings) without its own type",
                                                    "line 2: .trace_settings()"]


def test_nothing_below_the_scene_layer_takes_the_resolved_scene():
    found = []
    for mod, path in MODULES.items():
        if LAYERS[_package(mod)] < LAYERS["scene"]:
            found += [f"{mod} {u}" for u in _scene_uses(ast.parse(path.read_text(encoding="utf-8")))]
    assert found == []


def test_the_checker_finds_a_cycle():
    """The cycle finder itself, on a graph with one cycle and one chain (else a pass means nothing)."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    edges, _ = _graph()
    assert sum(len(v) for v in edges.values()) > 100  # the walk sees the package's imports
    assert _cycles(edges) == []


def test_no_private_name_imported_from_another_module():
    _, private = _graph()
    assert private == []


def test_no_function_over_100_lines():
    long = []
    for mod, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{mod}.{node.name}: {n} lines")
    assert long == []


@pytest.mark.parametrize("name", ["cloud_albedo", "earth_order", "moon_albedo_map"])
def test_an_option_lives_in_few_modules(name):
    """An option is one schema declaration plus the code that uses it: not restated elsewhere."""
    where = sorted(m for m, p in MODULES.items() if name in p.read_text(encoding="utf-8"))
    assert "lunarviz.options" in where
    assert len(where) <= 3 if name == "cloud_albedo" else len(where) <= 8, where


def test_readme_is_short():
    n = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert n <= 200, f"README.md has {n} lines; the user guide lives in docs/"


def test_every_data_file_ships_in_the_wheel():
    """pyproject's package-data globs cover every file under lunarviz/data (the packaged meshes
    included) and py.typed, so a wheel built from the checkout needs no checkout beside it."""
    import fnmatch

    import tomllib

    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["lunarviz"]
    files = [p.relative_to(PKG).as_posix() for p in (PKG / "data").rglob("*") if p.is_file()
             and "__pycache__" not in p.parts]
    assert any(f.startswith("meshes/") for f in (p.removeprefix("data/") for p in files))
    missing = [f for f in files + ["py.typed"] if not any(fnmatch.fnmatch(f, g) for g in globs)]
    assert missing == []
    assert (PKG / "py.typed").is_file()


def test_an_analytic_sweep_imports_no_heavy_package(tmp_path):
    # start-up: a one-phase analytic sweep from the command line loads neither
    # the viewers (PyVista, trame), nor the table and sky packages (xarray, astropy), nor the
    # tracer's meshes (trimesh, Embree): the modules are listed after the command has run
    import subprocess
    import sys
    code = ("import sys; from lunarviz.cli import main; "
            f"main(['sweep', '--method', 'analytic', '--phases', '90', '--out', r'{tmp_path / 's.json'}', '--quiet']); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & "
            "{'pyvista', 'trame', 'xarray', 'astropy', 'trimesh', 'embreex', 'vtk', 'vtkmodules', 'matplotlib'}))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "[]"


def test_one_module_name_means_one_thing():
    """No two modules of the package share a file name (``__init__`` aside): a name says what
    its module holds, wherever it is imported from."""
    from collections import Counter
    names = Counter(p.name for p in PKG.rglob("*.py") if p.name != "__init__.py")
    assert sorted(n for n, k in names.items() if k > 1) == []

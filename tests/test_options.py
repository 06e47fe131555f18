"""The option schema (lunarviz.options) against everything derived from it.

Walks every :class:`~lunarviz.options.Option` and proves it has a command-line flag, a Scene
keyword, a default that validates, a unit where it has one, and a place in the docstring, the
settings and their JSON round trip; then that a non-default value given on the command line
reaches the settings, and that a bad value is refused naming the option.
"""

from __future__ import annotations

import dataclasses
import json

import pytest

import lunarviz
from lunarviz.api import SCENE_DEFAULTS
from lunarviz.cli import SCENE_GROUPS, build_parser
from lunarviz.errors import LunarvizError
from lunarviz.methods.tracer.settings import TraceSettings
from lunarviz.options import BY_NAME, GROUPS, OPTIONS, group, scene_options
from lunarviz.scene import ResolvedScene

#: option kinds that carry a physical quantity, and so a unit
QUANTITIES = ("float", "xyz")
#: command-line text of a valid, non-default value per option kind or name
OTHER_VALUE = {"int": ("3", 3), "float": ("0.5", 0.5)}
CHOICE_KINDS = ("str",)


def _parse(*argv):
    return build_parser().parse_args(["sweep", "--out", "x.json", *argv])


def test_schema_is_well_formed():
    names = [o.name for o in OPTIONS]
    flags = [o.cli_flag for o in OPTIONS]
    assert len(set(names)) == len(names), "an option is declared twice"
    assert len(set(flags)) == len(flags), "two options share a flag"
    assert {o.group for o in OPTIONS} <= set(GROUPS)
    for o in OPTIONS:
        assert o.doc and o.doc[0].islower() or o.doc[0].isupper(), o.name
        assert o.cli_flag.startswith("--"), o.name


@pytest.mark.parametrize("opt", OPTIONS, ids=lambda o: o.name)
def test_every_option_has_flag_keyword_default_unit(opt):
    # a keyword of lunarviz.Scene, with the schema's default
    assert SCENE_DEFAULTS[opt.name] == opt.default
    # a default that validates (and is returned unchanged, up to tuple normalisation)
    assert opt.check(opt.default) == opt.default
    # a unit where it has one: quantities, and names that carry a unit suffix
    if opt.kind in QUANTITIES or opt.name.endswith(("_deg", "_m", "_s")):
        assert opt.unit, f"{opt.name} has no unit"
    # a flag on the sweep command, whose parsed default gives the schema's default
    given = scene_options(_parse(), {"brdfs": lambda t, _: tuple(t.split(",")),
                                     "params": lambda v, _: v, "detector": lambda v, _: v})
    assert opt.name in given, f"{opt.cli_flag} missing from `lunarviz sweep`"
    assert given[opt.name] == opt.default
    # documented in Scene's docstring, with its flag
    assert f"{opt.name} :" in lunarviz.Scene.__doc__ and f"``{opt.cli_flag}``" in lunarviz.Scene.__doc__
    # a field of the sweep's settings
    assert opt.name in {f.name for f in dataclasses.fields(ResolvedScene)}


def test_trace_settings_are_their_groups():
    fields = {f.name for f in dataclasses.fields(TraceSettings)}
    assert {o.name for o in group(*TraceSettings.GROUPS)} <= fields
    assert not {o.name for o in group("photometry", "analytic", "geometry", "sky")} & fields


def test_every_scene_command_has_every_scene_option():
    parser = build_parser()
    for cmd in ("sweep", "trace", "render", "view", "image"):
        args = parser.parse_args([cmd, "--out", "x.png"] if cmd != "view" else [cmd])
        for o in group(*SCENE_GROUPS):
            assert hasattr(args, o.dest), f"lunarviz {cmd} lacks {o.cli_flag}"


@pytest.mark.parametrize("opt", [o for o in OPTIONS if o.kind in OTHER_VALUE or (o.choices and o.kind == "str")],
                         ids=lambda o: o.name)
def test_a_flag_reaches_the_settings(opt):
    """A non-default value on the command line arrives in the scene's settings."""
    if opt.kind in OTHER_VALUE:
        text, value = OTHER_VALUE[opt.kind]
        if opt.hi is not None and value > opt.hi or opt.name.endswith("_level"):
            text, value = "2", 2
    else:
        value = next(c for c in opt.choices if c != opt.default)
        text = value
    if opt.name == "earth_rotation_deg":
        text, value = "30", 30.0
    args = _parse(opt.cli_flag, text, "--method", "raytrace")
    kw = scene_options(args, {"brdfs": lambda t, _: tuple(t.split(",")), "params": lambda v, _: None,
                              "detector": lambda v, _: None})
    assert kw[opt.name] == value
    if opt.name == "estimator":
        return  # the settings check it against the method; the value is what matters here
    if opt.group == "spectral" and opt.name not in ("wavelengths", "bands"):
        kw["wavelengths"] = "500"  # the spectral run's own options are refused in a grey run
    settings = lunarviz.Scene(phases="90", **kw).settings("raytrace")
    assert getattr(settings, opt.name) == value


@pytest.mark.parametrize("opt", [o for o in OPTIONS if o.lo is not None or o.hi is not None or
                                 (o.choices and o.kind == "str")], ids=lambda o: o.name)
def test_a_bad_value_is_refused_naming_the_option(opt):
    bad = "no-such-value" if opt.kind == "str" else (opt.lo - 1 if opt.lo is not None else opt.hi + 1)
    with pytest.raises(LunarvizError) as err:
        lunarviz.Scene(phases="90", **{opt.name: bad})
    assert str(bad) in str(err.value)
    assert opt.what.split()[0].lower() in str(err.value).lower() or opt.name in str(err.value)


def test_settings_round_trip_through_json():
    """``settings`` as written (JSON) reread into the same settings, for a scene with options
    of every group set away from their defaults."""
    scene = lunarviz.Scene(phases="30,90", brdfs=("lambert", "dhg"), rays=1234, runs=2, seed=7, earth_order=4,
                           shading="flat", occlusion=False, cloud_albedo=0.5, clouds="zonal",
                           earth_surface="landocean", detector=(0.0, 1e5, 0.0), params={"dhg": {"b": 0.3}},
                           h_function="hapke2002", grid="paper", order=16, earth_rotation_deg=15.0)
    settings = scene.settings("raytrace")
    again = ResolvedScene.from_dict(json.loads(json.dumps(settings.to_dict())))
    assert again == settings


def test_dataset_settings_json_reruns_the_sweep():
    ds = lunarviz.sweep(phases="60", brdfs=("lambert",), earth_albedo=0.35)
    settings = ResolvedScene.from_dict(json.loads(ds.attrs["settings_json"]))
    assert settings.earth_albedo == 0.35 and settings.phases_deg == (60.0,)
    again = lunarviz.run(lunarviz.Scene(phases="60", brdfs=("lambert",), earth_albedo=0.35))
    assert [r["moonshine_W_m2"] for r in again["rows"]] == list(ds.moonshine.values.ravel())


def test_options_table_names_every_option():
    """BY_NAME is the schema, keyed by keyword."""
    assert list(BY_NAME) == [o.name for o in OPTIONS]


#: one new Earth option and one new traced option, declared in the schema in a fresh process before
#: anything else is imported: the worked examples of docs/architecture.md ("Options: one declaration each")
NEW_OPTIONS_DRIVER = r'''
import json
import lunarviz.options as o
new = (o.Option("sea_ice_albedo", "float", 0.6, "Lambert albedo of sea ice", "earth", unit="1", lo=0.0, hi=1.0,
                label="sea ice albedo"),
       o.Option("lune_samples", "int", 16, "lunar samples across the lit lune", "trace", lo=2, hi=256))
o.OPTIONS = o.OPTIONS + new
o.BY_NAME.update((x.name, x) for x in new)
from lunarviz.api import Scene
from lunarviz.cli import build_parser
from lunarviz.errors import LunarvizError
from lunarviz.scene import ResolvedScene
a = build_parser().parse_args(["sweep", "--sea-ice-albedo", "0.7", "--lune-samples", "24", "--out", "x.json"])
scene = Scene(phases="90", sea_ice_albedo=a.sea_ice_albedo, lune_samples=a.lune_samples)
rs = scene.settings("raytrace")
try:
    Scene(phases="90", sea_ice_albedo=1.5)
    refused = ""
except LunarvizError as exc:
    refused = str(exc)
print(json.dumps({
    "scene_doc": "sea_ice_albedo" in Scene.__doc__ and "lune_samples" in Scene.__doc__,
    "resolved": [rs.sea_ice_albedo, rs.lune_samples],
    "round_trip": ResolvedScene.from_json(rs.to_json()) == rs and "sea_ice_albedo" in rs.to_json(),
    "trace_settings": [rs.trace_settings().sea_ice_albedo, rs.trace_settings().lune_samples],
    "earth_model": rs.earth_model().sea_ice_albedo,
    "model_earth": o.model_earth(rs)["sea_ice_albedo"],
    "refused": refused}))
'''


def test_a_new_option_reaches_every_layer_from_one_declaration(tmp_path):
    """Adding an option is its declaration (and the code that uses it): with two new options in the
    schema, nothing else written, the command line parses them, the Scene documents and checks
    them, the resolved scene carries and round-trips them, the tracer's settings and the Earth model
    have them, and the model Earth of every inversion resets the Earth's."""
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-c", NEW_OPTIONS_DRIVER], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["scene_doc"] and got["round_trip"]
    assert got["resolved"] == [0.7, 24] and got["trace_settings"] == [0.7, 24]
    assert got["earth_model"] == 0.7 and got["model_earth"] == 0.6
    assert got["refused"] == "sea ice albedo 1.5 must be a finite number in [0, 1]"

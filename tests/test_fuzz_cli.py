"""Fuzzing the one-line promise: any value for any scene option ends in a result (exit 0) or
in exactly one line ``lunarviz: error: …`` (exit 2), never a traceback, and leaves no output
file behind on error. Values are drawn from what breaks parsers: empty, huge, tiny, NaN and
infinities, negative, lists, long strings, paths that do not exist, control characters."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lunarviz.cli import SCENE_GROUPS, main
from lunarviz.options import group

OPTIONS = [o for o in group(*SCENE_GROUPS, "analytic", "spectral") if o.kind != "bool"]
NASTY = ["", " ", "0", "-1", "1", "2", "0.5", "1e308", "-1e308", "1e-320", "nan", "inf", "-inf", "1,2",
         "1,2,3", "a,b,c", "x" * 300, "/nonexistent/file.ply", "../../etc/passwd", "none", "zonal", "landocean",
         "site:91,0", "orbit:-5,0,0,0", "tle:/dev/null", "geocentre", "2026-13-45", "\x00", "é", "0:180:0",
         "lambert,foo", "w=2", "dhg.b=0.5", "b=nan", "V", "v,B", "S2A-B4", "400-750", "750-400", "band.csv",
         "300:2600:1", "550", "grey", "tsis1-hsrs", "surface", "8ms", "1" + "0" * 400]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(opt=st.sampled_from(OPTIONS), value=st.one_of(st.sampled_from(NASTY),
                                                      st.text(min_size=0, max_size=40),
                                                      st.floats(allow_nan=True, allow_infinity=True).map(repr)))
def test_any_value_ends_in_a_result_or_one_line(tmp_path_factory, capsys, opt, value):
    if "\x00" in value:
        value = value.replace("\x00", "")  # argv cannot carry NUL bytes
    out = tmp_path_factory.mktemp("fuzz") / "f.json"
    argv = ["sweep", "--method", "analytic", "--phases", "90", "--brdf", "lambert", "--quiet",
            "--out", str(out), opt.cli_flag, value]
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse's own exits (there are none for these flags; kept honest)
        rc = exc.code
    err = capsys.readouterr().err
    assert rc in (0, 2), (opt.cli_flag, value, rc, err[-800:])
    if rc == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("lunarviz: error:"), (opt.cli_flag, value, err[-800:])
        assert not out.exists()
    else:
        assert out.exists()


@pytest.mark.parametrize("value", ["tle:/dev/null", "site:91,0", "orbit:-5,0,0,0"])
def test_bad_observers_with_a_date_are_one_line(tmp_path, capsys, value):
    rc = main(["sweep", "--time", "2026-06-03T00:00Z", "--observer", value, "--quiet", "--out",
               str(tmp_path / "o.json")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and err.startswith("lunarviz: error:"), err


NASTY_JSON = [None, True, 0, -1, 1e308, float("nan"), "", "x", [], {}, [1, 2], {"a": 1}, 10**400, "120,130", "../x"]


@settings(max_examples=60, deadline=None)
@given(key=st.sampled_from(sorted(__import__("lunarviz.instrument.spec", fromlist=["Instrument"])
                                  .Instrument.__dataclass_fields__)),
       value=st.one_of(st.sampled_from(NASTY_JSON), st.text(max_size=30), st.floats(), st.integers()))
def test_any_instrument_value_is_an_instrument_or_one_line(key, value):
    """Each field of an instrument file set to anything: an instrument, or a one-line error."""
    import json

    from lunarviz.errors import LunarvizError
    from lunarviz.instrument.spec import instrument_from_dict, load_instrument
    d = load_instrument("salex").to_dict()
    d[key] = value
    try:
        inst = instrument_from_dict(json.loads(json.dumps(d, allow_nan=True)))
    except LunarvizError as exc:
        assert "\n" not in str(exc)
    else:
        assert inst.width >= 8 and inst.exposure_s > 0


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(["instrument_spec", "exposure_s", "key", "feasible"]),
       value=st.sampled_from(NASTY_JSON + [1e-300, 1e6, "salex", "2026-01-01T00:00Z"]))
def test_any_plan_file_is_a_plan_or_one_line(tmp_path_factory, field, value):
    """A plan file (``plan --out``) with any field set to anything: read, or a one-line error."""
    import json

    from lunarviz.errors import LunarvizError
    from lunarviz.workflows.measurement import read_plan
    d = {"instrument_spec": "salex", "exposure_s": 0.01, "key": "120.0", "feasible": True, field: value}
    f = tmp_path_factory.mktemp("plan") / "p.json"
    f.write_text(json.dumps(d, allow_nan=True))
    try:
        p = read_plan(f)
    except LunarvizError as exc:
        assert "\n" not in str(exc)
    else:
        assert 1e-6 <= p["exposure_s"] <= 1e5 and p["key"]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=4000), head=st.sampled_from([b"", b"SIMPLE  =                    T", b"\x1f\x8b",
                                                           b"PK\x03\x04", b"BZh"]))
def test_any_bytes_as_frames_are_one_line(tmp_path_factory, capsys, data, head):
    """``lunarviz measure FILE`` of any bytes: one line, exit 2 (a FITS header, a compressed file)."""
    f = tmp_path_factory.mktemp("frames") / "f.fits"
    f.write_bytes(head + data)
    rc = main(["measure", str(f), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and err.startswith("lunarviz: error:"), err[-500:]


@settings(max_examples=150, deadline=None)
@given(text=st.one_of(st.text(max_size=20), st.sampled_from(["8ms", "8 MS", "1e400s", "nan", "-0s", "μs", "5min",
                                                             "1" + "0" * 400 + "us"])))
def test_any_exposure_text_is_seconds_or_one_line(text):
    from lunarviz.errors import LunarvizError
    from lunarviz.parsing import TIME_S, parse_quantity
    try:
        v, _ = parse_quantity(text, "exposure", TIME_S, "s")
    except LunarvizError as exc:
        assert "\n" not in str(exc)
    else:
        assert v == v and abs(v) < float("inf")

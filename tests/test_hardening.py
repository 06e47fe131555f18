"""Bounded resources and honest failures on crafted input: each case ends with one line
(LunarvizError/MeshError, exit 2 on the command line), before anything large is decoded."""

from __future__ import annotations

import bz2
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from lunarviz.bodies.meshes import MeshError, load_user_mesh
from lunarviz.errors import LunarvizError
from lunarviz.surfaces.maps import MAX_MAP_CELLS, read_grid

TINY_PLY = b"""ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 4
property list uchar int vertex_indices
end_header
1 1 1
-1 -1 1
-1 1 -1
1 -1 -1
3 0 1 2
3 0 3 1
3 0 2 3
3 1 3 2
"""


def test_compressed_mesh_is_refused_before_decompression(tmp_path):
    p = tmp_path / "bomb.ply.bz2"
    p.write_bytes(bz2.compress(TINY_PLY + b"0 " * 10_000_000))  # ~10 kB that would inflate to 20 MB
    with pytest.raises(MeshError, match="unsupported mesh format '.bz2'"):
        load_user_mesh(p, units="radius")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this platform")
def test_fifo_mesh_and_map_are_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.ply"
    os.mkfifo(fifo)
    with pytest.raises(MeshError, match="not a regular file"):
        load_user_mesh(fifo, units="radius")
    fifo_map = tmp_path / "pipe.npy"
    os.mkfifo(fifo_map)
    with pytest.raises(LunarvizError, match="not a regular file"):
        read_grid(fifo_map)
    gltf = tmp_path / "m.gltf"
    os.mkfifo(tmp_path / "buffer.bin")
    gltf.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "buffer.bin", "byteLength": 8}]}))
    with pytest.raises(MeshError, match="buffer 'buffer.bin'"):
        load_user_mesh(gltf, units="radius")


@pytest.mark.parametrize("side", [int(np.sqrt(MAX_MAP_CELLS)) + 100, 10_000])
def test_oversized_image_map_is_refused_before_decoding(tmp_path, side):
    """Above our cap (5e7 cells), and above Pillow's own bomb-warning threshold (8.9e7 pixels),
    whose warning used to print before the one error line."""
    from PIL import Image
    p = tmp_path / "bomb.png"
    Image.new("1", (side, side)).save(p)  # a few kB on disk, 50-100 M pixels decoded
    assert p.stat().st_size < 1_000_000
    with pytest.raises(LunarvizError, match="pixels is more than"):
        read_grid(p)  # (pytest's filterwarnings = error turns a leaked bomb warning into a failure)


def test_cli_refuses_a_compressed_mesh_in_one_line(tmp_path):
    p = tmp_path / "moon.ply.gz"
    p.write_bytes(b"\x1f\x8b" + b"\0" * 100)
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--method", "raytrace", "--phases", "90",
                        "--moon-mesh", str(p), "--out", str(tmp_path / "x.json")], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "unsupported mesh format '.gz'" in r.stderr
    assert not (tmp_path / "x.json").exists()


def _children(pid: int) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(d))
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to list worker processes")
def test_sigterm_ends_the_workers_and_leaves_no_file(tmp_path):
    """SIGTERM to a sweep's parent: one line, exit 130, no result or temporary file, and no
    worker left running (they used to outlive the parent by minutes)."""
    import signal
    import time
    proc = subprocess.Popen([sys.executable, "-m", "lunarviz", "sweep", "--method", "raytrace", "--phases",
                             "0:180:10", "--workers", "2", "--out", str(tmp_path / "s.json"), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    deadline = time.time() + 60
    kids = []
    while time.time() < deadline and len(kids) < 2 and proc.poll() is None:
        time.sleep(0.5)
        kids = _children(proc.pid)
    assert proc.poll() is None and kids, "the sweep ended before its workers could be seen"
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and err.strip() == "lunarviz: interrupted", (proc.returncode, err[-2000:])
    deadline = time.time() + 20  # terminated workers may take a moment to go on a loaded machine
    while time.time() < deadline and [k for k in kids if _alive(k)]:
        time.sleep(0.2)
    assert not [k for k in kids if _alive(k)]
    assert os.listdir(tmp_path) == []


def test_a_plot_replaces_a_symlink_instead_of_writing_through_it(tmp_path):
    """`ln -s victim.txt fitx.png`: the figure replaces the link; the victim is untouched."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lunarviz.outputs.writers import save_figure
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (tmp_path / "fitx.png").symlink_to(victim)
    fig = plt.figure()
    save_figure(fig, tmp_path / "fitx.png")
    plt.close(fig)
    assert victim.read_text() == "keep me"
    assert not (tmp_path / "fitx.png").is_symlink() and (tmp_path / "fitx.png").read_bytes()[:4] == b"\x89PNG"


def test_multiblock_output_leaves_a_users_folder_alone(tmp_path):
    """Writing scene.vtm used to delete a user's folder named .scene.tmp/."""
    import lunarviz
    (tmp_path / ".scene.tmp").mkdir()
    (tmp_path / ".scene.tmp" / "mine.txt").write_text("mine")
    f = lunarviz.trace(lunarviz.Scene(phases=90.0, brdfs=("lambert",), moon_level=1, earth_level=2, sun_level=1))
    f.save(tmp_path / "scene.vtm")
    assert (tmp_path / ".scene.tmp" / "mine.txt").read_text() == "mine"
    assert (tmp_path / "scene.vtm").is_file() and (tmp_path / "scene").is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == [".scene.tmp", "scene", "scene.vtm"]


def test_a_plot_path_that_is_a_folder_is_refused_before_any_work(tmp_path):
    (tmp_path / "fit.png").mkdir()
    table = tmp_path / "t.csv"
    table.write_text("phase_deg,reflectance\n10,0.1\n20,0.09\n30,0.08\n40,0.07\n")
    r = subprocess.run([sys.executable, "-m", "lunarviz", "fit", "--model", "lambert", "--source", str(table),
                        "--out", str(tmp_path / "fit.json")], capture_output=True, text=True)
    assert r.returncode == 2 and "is a directory" in r.stderr and r.stderr.count("\n") == 1
    assert not (tmp_path / "fit.json").exists()


@pytest.mark.parametrize("case", ["huge_obj", "dem_scale", "waxing_inf", "tiny_reflectance"])
def test_extreme_values_end_in_one_line(tmp_path, case):
    """Inputs that raised OverflowError/ValueError tracebacks: now one line and exit 2."""
    if case == "huge_obj":
        (tmp_path / "big.obj").write_text("v 1e306 0 0\nv 0 1e306 0\nv 0 0 1e306\nv -1e306 -1e306 -1e306\n"
                                          "f 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n")
        args = ["sweep", "--method", "raytrace", "--phases", "90", "--moon-mesh", "big.obj", "--out", "x.json"]
    elif case == "dem_scale":
        np.save(tmp_path / "h.npy", np.ones((8, 16)))
        args = ["mesh", "make", "dem", "--dem", "h.npy", "--height-scale", "1e300", "--level", "1", "--out", "d.ply"]
    else:
        (tmp_path / "t.csv").write_text("phase_deg,reflectance,waxing\n10,0.1,1\n20,0.09,1\n30,0.08,1\n"
                                        + ("40,0.07,inf\n" if case == "waxing_inf" else "40,5e-324,1\n"))
        args = ["fit", "--model", "lambert", "--source", "t.csv", "--out", "f.json"]
    r = subprocess.run([sys.executable, "-m", "lunarviz", *args], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith("lunarviz: error:") and r.stderr.count("\n") == 1, r.stderr
    assert not [p for p in os.listdir(tmp_path) if p.endswith((".json", ".ply", ".png"))]


def test_api_output_of_the_wrong_type_is_one_error():
    import lunarviz
    with pytest.raises(LunarvizError, match="must be a path"):
        lunarviz.image(lunarviz.Scene(phases="90", moon_level=1), 90.0, pixels=16, out=123)


def test_a_detector_on_the_moon_is_refused():
    """1 km above the sub-solar point the ray tracer gave 0.11 W m-2 where the exact answer is
    57.8: a detector closer than 10 lunar radii to the Moon's centre is refused in one line."""
    import lunarviz
    R = 1.738e6
    with pytest.raises(LunarvizError, match="lunar radii"):
        lunarviz.Scene(phases="90", detector=(0.0, 3.8e8 - R - 1e3, 0.0))
    lunarviz.Scene(phases="90", detector=(0.0, 3.8e8 - 12 * R, 0.0))  # a detector well away: accepted


def test_an_observer_inside_the_earth_is_refused(monkeypatch):
    """A decayed TLE propagated far from its epoch put the observer 1772 km from the Earth's
    centre and fluxes were reported: now one line naming the observer and the date."""
    from lunarviz.sky import observers
    from lunarviz.sky.dated_scene import sky_scene
    monkeypatch.setattr(observers.Observer, "position", lambda self, label: np.array([1.772e6, 0.0, 0.0]))
    obs = observers.Observer(kind="orbit", spec="orbit:test-decayed", alt_km=500.0)
    with pytest.raises(LunarvizError, match="inside the Earth"):
        sky_scene("2031-02-03T04:05:06Z", obs)


def test_a_lobe_narrower_than_the_earth_is_refused(tmp_path):
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--method", "analytic", "--brdf", "dhg",
                        "--param", "b=0.999999", "--phases", "90", "--out", str(tmp_path / "b.json")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "narrower than the Earth's disc" in r.stderr and r.stderr.count("\n") == 1


def test_numbered_frames_are_all_or_nothing(tmp_path, monkeypatch):
    """A folder where frame 1 goes is refused before any work (it used to leave fr_000.npy and
    name a temporary file); a failure at the last frame leaves no frame at all."""
    import lunarviz
    from lunarviz.workflows import tasks
    scene = lunarviz.Scene(phases="30,60,90", brdfs=("lambert",), moon_level=1, earth_level=2, sun_level=1)
    (tmp_path / "fr_001.npy").mkdir()
    with pytest.raises(LunarvizError, match="fr_001.npy' is a directory"):
        lunarviz.image(scene, keys=[30.0, 60.0, 90.0], pixels=16, supersample=1, out=tmp_path / "fr.npy")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fr_001.npy"]
    (tmp_path / "fr_001.npy").rmdir()
    real = tasks.synthesize
    calls = []

    def fail_last(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise LunarvizError("stop at the last frame")
        return real(*a, **k)
    monkeypatch.setattr(tasks, "synthesize", fail_last)
    with pytest.raises(LunarvizError, match="last frame"):
        lunarviz.image(scene, keys=[30.0, 60.0, 90.0], pixels=16, supersample=1, out=tmp_path / "fr.npy")
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def full_disk(tmp_path):
    """A 64 KiB tmpfs (needs root and mount permission; skipped elsewhere)."""
    where = tmp_path / "full"
    where.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(where)], capture_output=True)
    if r.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    yield where
    subprocess.run(["umount", str(where)], capture_output=True)


@pytest.mark.parametrize("out", ["m.ply", "m.vtp", "s.vtm", "x.nc", "x.json"])
def test_a_full_disk_is_one_line_and_no_file(full_disk, out):
    """trace used to print 'wrote' with a truncated .ply and exit 0, .vtm left 0-byte files,
    and a NetCDF on a full disk crashed the process (rc 139)."""
    if out.endswith((".nc", ".json")):
        # outputs of 108 kB (NetCDF) and 193 kB (JSON): three times what the 64 KiB disk holds
        args = ["sweep", "--phases", "0:179:0.5" if out.endswith(".nc") else "0:179:1", "--brdf", "lambert,dhg"]
    else:
        args = ["trace", "--phase", "90", "--brdf", "lambert"]
    r = subprocess.run([sys.executable, "-m", "lunarviz", *args, "--out", str(full_disk / out), "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 2, r.stderr[-500:]
    said = [line for line in r.stderr.splitlines() if not line.startswith("lunarviz: warning:")]  # (rows unbounded)
    assert len(said) == 1 and said[0].startswith("lunarviz: error:"), r.stderr[-1500:]
    assert "cannot write" in r.stderr or "incomplete" in r.stderr or "disk full" in r.stderr, r.stderr
    assert os.listdir(full_disk) == []


def test_analytic_near_new_moon_is_refused_not_zero(tmp_path):
    """At θ = 179.9° the analytic method's point Sun gave exactly 0 where the exact reference is
    9.8e-15 W m-2: within 1° of new Moon it is refused; θ = 180° itself (reference 4e-20) is kept."""
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--method", "analytic", "--phases", "179.9",
                        "--out", str(tmp_path / "a.json")], capture_output=True, text=True)
    assert r.returncode == 2 and "--method raytrace or reference" in r.stderr and r.stderr.count("\n") == 1
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--method", "analytic", "--phases", "0:180:5",
                        "--quiet", "--out", str(tmp_path / "b.json")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_web_viewer_caps_what_a_client_may_announce():
    """wslink let a logged-in client announce a 1 GiB message (two 16-byte chunk headers grew the
    server from 0.48 to 2.6 GB): the viewer's server caps the allocation at 16 MiB."""
    pytest.importorskip("wslink")

    from wslink import chunking

    from lunarviz.viz.web import MAX_CLIENT_MESSAGE_BYTES, cap_client_messages
    cap_client_messages()
    un = chunking.UnChunker()
    un.set_max_message_size(4 * 1024 ** 3)  # what wslink does after a successful login
    assert un.max_message_size == MAX_CLIENT_MESSAGE_BYTES
    header = chunking._encode_header(1, 0, 1 << 30)  # noqa: SLF001 (wslink's own header format): 1 GiB
    assert len(header) == chunking.HEADER_LENGTH
    with pytest.raises(ValueError, match="exceeds the allocation limit"):
        un.process_chunk(header + b"x")


def test_an_output_name_the_system_refuses_is_exit_2(tmp_path):
    """A file name too long for the file system was exit 1 (the OSError path); every input and
    output failure is exit 2 with one line."""
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--phases", "90", "--brdf", "lambert",
                        "--out", "a" * 300 + ".json"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.startswith("lunarviz: error:") and r.stderr.count("\n") == 1, r.stderr
    assert os.listdir(tmp_path) == []


def test_a_repeated_warning_is_printed_once(tmp_path):
    """The TLE-age warning came three times for one date (the settings are checked more than once)."""
    tle = os.path.join(os.path.dirname(__file__), "data", "leo_2027.tle")
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--method", "analytic", "--brdf", "lambert",
                        "--moon-model", "paper", "--time", "2027-03-15T00:00Z", "--observer", f"tle:{tle}",
                        "--quiet", "--out", str(tmp_path / "t.json")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("lunarviz: warning:") == 1, r.stderr

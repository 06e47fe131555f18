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
from lunarviz.bodies.surfaces import MAX_MAP_CELLS, read_grid
from lunarviz.errors import LunarvizError

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


def test_oversized_image_map_is_refused_before_decoding(tmp_path):
    from PIL import Image
    side = int(np.sqrt(MAX_MAP_CELLS)) + 100
    p = tmp_path / "bomb.png"
    Image.new("1", (side, side)).save(p)  # a few kB on disk, 50 M pixels decoded
    assert p.stat().st_size < 1_000_000
    with pytest.raises(LunarvizError, match="pixels is more than"):
        read_grid(p)


def test_cli_refuses_a_compressed_mesh_in_one_line(tmp_path):
    p = tmp_path / "moon.ply.gz"
    p.write_bytes(b"\x1f\x8b" + b"\0" * 100)
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--method", "raytrace", "--phases", "90",
                        "--moon-mesh", str(p), "--out", str(tmp_path / "x.json")], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "unsupported mesh format '.gz'" in r.stderr
    assert not (tmp_path / "x.json").exists()

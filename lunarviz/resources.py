"""Where the files that ship inside the package live (data tables, maps, packaged meshes)."""

from __future__ import annotations

from pathlib import Path

#: the package's data folder: presets, maps, cloud tables, and ``meshes/`` with its manifest
DATA_DIR = Path(__file__).resolve().parent / "data"
#: packaged icosphere meshes and their ``manifest.json`` (sha256 of each file)
MESH_DIR = DATA_DIR / "meshes"

"""Regenerate the packaged meshes in lunarviz/data/meshes/ (meshes/ links there) and their manifest (sha256 checksums).

    python scripts/make_meshes.py
"""

from lunarviz.bodies.meshes import write_packaged_meshes

if __name__ == "__main__":
    print(write_packaged_meshes({"sun": [5], "earth": [6], "moon": [2, 3, 4, 5, 6]}))

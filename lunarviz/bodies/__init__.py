"""The bodies: packaged and user meshes, shapes (ellipsoid, DEM, craters, patch) and surface maps."""

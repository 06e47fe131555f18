"""Photometry: lunar BRDFs and roughness, parameter presets, fits, the Earth's phase law and
the albedo inversion."""

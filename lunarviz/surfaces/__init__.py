"""Surfaces of the bodies: equirectangular maps and what they hold (the lunar albedo, the Earth's
land, ocean and clouds, the physical Earth's reflectance), read per facet or at points."""

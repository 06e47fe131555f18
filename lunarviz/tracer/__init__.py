"""Embree ray tracing of the Sun-Earth-Moon scene (see :mod:`lunarviz.tracer.estimators`)."""

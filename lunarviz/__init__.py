"""lunarviz: real-scale ray-traced earthshine and moonshine (see README.md)."""

__version__ = "0.1.0"


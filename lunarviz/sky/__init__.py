"""The real sky: ephemerides, observers and the scene at a UTC time."""

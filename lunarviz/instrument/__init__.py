"""Instruments: an imager (optics, band, detector), its frames in counts, the measurement pipeline
that turns them into the Earth's apparent albedo, its error budget, and exposure planning."""

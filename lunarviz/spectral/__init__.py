"""Light in colour: the solar spectrum, bands, the spectral request and inputs, the spectral Moon,
and shading one transport at every wavelength."""

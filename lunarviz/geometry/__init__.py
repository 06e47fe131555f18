"""Scene geometry: body positions and angles (paper Eq. 3) and quadrature on spheres."""

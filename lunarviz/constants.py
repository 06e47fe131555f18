"""Physical constants of the paper's scene, in SI units, each with its source.

The paper is *Real Scale Ray Tracing Simulation of Space Earthshine Measurement with Improved
BRDF Model of Lunar Surface* (Sec. 2.1-2.3, Tables 1-2); "paper notes" are the documentation's
page on how lunarviz reads it (docs/paper_notes.md).
"""

#: Sun-Earth distance [m]; paper Sec. 2.1.2 (D_SE = 1.496e11 m).
D_SE_M = 1.496e11
#: Earth-Moon distance [m]; paper Sec. 2.1.2 (D_EM = 3.800e8 m).
D_EM_M = 3.800e8
#: Lunar radius [m]; paper Sec. 2.1.2 (R_Moon = 1.738e6 m).
R_MOON_M = 1.738e6
#: Earth radius [m]; paper Sec. 2.2 (R_Earth = 6.378e6 m, equatorial).
R_EARTH_M = 6.378e6
#: Solar radius [m]; not given in the paper. IAU 2015 Resolution B3 nominal solar radius.
R_SUN_M = 6.957e8
#: Solar radiant flux over 400-750 nm [W]; paper abstract and Sec. 2.1.2 (1.626e26 W).
PHI_SUN_W = 1.626e26
#: Earth Bond albedo of the Lambertian Earth; paper abstract (0.3).
EARTH_ALBEDO = 0.3
#: Albedo of the Lambertian Moon; paper Table 5 header "Lambertian(0.10)" (paper notes, item 6).
MOON_LAMBERT_ALBEDO = 0.10
#: Monte Carlo rays per run and runs per phase; paper Sec. 3.2 (paper notes, item 8).
PAPER_RAYS = 50_000
PAPER_RUNS = 10
#: Phase grid of the paper's sweep [deg]; paper Sec. 3.2 (0..180 in 5 deg steps).
PAPER_PHASES_DEG = tuple(float(p) for p in range(0, 181, 5))
#: Planck's constant [J s] (SI 2019, exact)
PLANCK_J_S = 6.62607015e-34
#: the speed of light in vacuum [m s⁻¹] (SI, exact)
SPEED_OF_LIGHT_M_S = 299_792_458.0
#: sea-level pressure [hPa] of Bodhaine et al.'s (1999) Rayleigh optical depth formula
SEA_LEVEL_HPA = 1013.25

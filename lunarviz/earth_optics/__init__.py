"""The Earth as it reflects: Rayleigh scattering, Cox–Munk ocean glint, land and snow BRDFs and
clouds, coupled into top-of-atmosphere reflectance factors per surface class.

Modules, one job each: :mod:`.rayleigh` (the molecular optical depth and phase function),
:mod:`.atmosphere` (the Rayleigh layer's reflectance, transmittance and spherical albedo from
the packaged DISORT tables, and their coupling with a surface), :mod:`.ocean`, :mod:`.land`,
:mod:`.cloud` (the surfaces), :mod:`.classes` (the classes by name: what ``lunarviz brdf --body
earth --surface`` takes). How the tables are made: the documentation's *Earth as it reflects* page.
"""

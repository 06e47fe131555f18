"""Shared fixtures and named tolerances (each says why it is that size)."""

import numpy as np
import pytest

from lunarviz.photometry.brdf import make_brdf

#: Round-off budget of float64 BRDF algebra (a few hundred ulps).
ROUNDOFF = 1e-12


@pytest.fixture(scope="session")
def paper_brdfs():
    """The paper's three lunar surfaces (Table 2, Table 5 header)."""
    return {k: make_brdf(k) for k in ("lambert", "shg", "dhg")}


@pytest.fixture
def rng():
    return np.random.default_rng(12345)

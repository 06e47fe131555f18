"""PyVista views (the only part of lunarviz that imports PyVista; loaded on first use)."""

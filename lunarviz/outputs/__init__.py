"""What lunarviz writes: atomic writers, tables (JSON/CSV/NetCDF), per-facet results, images."""

"""A minimal stand-in for Saleae Logic 2's ``saleae`` package, for tests only (Logic 2 does not run here)."""

"""Divergence instabilities of elastic bodies in frictional contact (FEniCSx)."""

__version__ = "0.1.0"   # keep equal to pyproject.toml's version

"""The package version (one place; read by :mod:`flexparcel`, the command line and the stores)."""

__all__ = ["__version__"]

__version__ = "0.1.0"

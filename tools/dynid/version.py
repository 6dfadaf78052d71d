"""The package version, in one place (written into model and coefficient files)."""

__version__ = "0.1.0"

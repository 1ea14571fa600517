"""The package's version (a module of its own, so every part can read it)."""

__version__ = "0.1.0"

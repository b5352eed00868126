"""The package's version: part of cache keys and of every recorded result."""

__version__ = "0.1.0"

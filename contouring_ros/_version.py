"""The package's version, alone: a node's process reads it without the package's API."""

__version__ = "0.1.0"

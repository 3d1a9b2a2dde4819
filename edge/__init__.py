"""edge: depth service for a smart structured-light sensor with redundancy codes."""

__version__ = "0.1.0"

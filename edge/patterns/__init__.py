"""Projector frames from codes: `render`, `calibration`, PNG export (`write_patterns`)."""

from .export import write_patterns
from .render import calibration, column_rows, render, symbol_levels

__all__ = ["render", "calibration", "column_rows", "symbol_levels", "write_patterns"]

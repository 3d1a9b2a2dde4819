"""Projector frames from codes: `render`, `calibration`, PNG export (`write_patterns`,
`write_opencv_graycode`), OpenCV's Gray-code layout (`opencv_graycode`) and the manifest format."""

from .export import write_opencv_graycode, write_patterns
from .manifest import LayoutSpec, parse_manifest, read_manifest
from .opencv import opencv_graycode
from .render import calibration, column_rows, render, symbol_levels

__all__ = ["render", "calibration", "column_rows", "symbol_levels", "write_patterns", "write_opencv_graycode",
           "opencv_graycode", "LayoutSpec", "parse_manifest", "read_manifest"]

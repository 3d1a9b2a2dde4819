"""Decoders: soft-decision ML, hard, list decoding with the order prior, confidence median
filter; EDC error maps; loaders for real capture layouts."""

from ..numba_cache import install as _install_cache_lock

_install_cache_lock()  # before any kernel of this package is compiled or loaded (edge.numba_cache)

from .check import check, check_capture, contrast_error_map, error_map
from .decoder import DEFAULTS, METHODS, Decoded, decode, decode_capture, decode_refined
from .inputs import NoPatternContrast
from .layouts import LayoutCapture, decode_axes, load_manifest, load_opencv_graycode
from .levels import refine_levels
from .settings import DEFAULT_SETTINGS, DecodeSettings
from .spatial import confidence_median, order_prior, spatial_outliers

__all__ = [
    "Decoded", "decode", "NoPatternContrast", "DecodeSettings", "DEFAULT_SETTINGS", "decode_refined", "refine_levels", "DEFAULTS", "METHODS", "check",
    "contrast_error_map", "error_map", "order_prior", "confidence_median", "spatial_outliers", "LayoutCapture", "load_opencv_graycode", "load_manifest", "decode_axes",
    "decode_capture", "check_capture", "LayoutCapture",
]

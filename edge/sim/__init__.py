"""Simulator: scenes with ground truth, image formation (eq. 1), global illumination, metrics.

Public API::

    make_scene(name, width, height, *, seed=0, geometry=None, **params) -> Scene
    CameraModel(bits=8, sigma_r=..., sigma_s=..., ambient=..., projector=..., exposure=1.0,
                total_exposure=10.0, defocus_sigma=0.0, sampling="nearest")
    capture(scene, projector_frames, camera, *, rng, exposure=None) -> (m, H, W) uint8/uint16
    capture_code(scene, code, camera, *, rng, stripe=1) -> edge.capture.CodedCapture
    evaluate(decoded_column, scene, *, valid=None, threshold=0, stripe=1) -> Metrics
"""

from ..numba_cache import install as _install_cache_lock

_install_cache_lock()  # before any kernel of this package is compiled or loaded (edge.numba_cache)

from .camera import SUPPORTED_BITS, CameraModel
from .geometry import DEPTH_RANGE_M, Geometry
from .metrics import Metrics, depth_from_columns, error_map, error_rate, evaluate
from .render import capture, capture_code, code_profiles, projector_irradiance
from .scene import Scene, build_scene
from .scenes import make_scene, min_scene_size, scene_names

__all__ = [
    "CameraModel", "DEPTH_RANGE_M", "Geometry", "Metrics", "SUPPORTED_BITS", "Scene",
    "build_scene", "capture", "capture_code", "code_profiles", "depth_from_columns", "error_map",
    "error_rate", "evaluate", "make_scene", "min_scene_size", "projector_irradiance", "scene_names",
]

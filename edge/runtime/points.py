"""The point cloud of a `DepthResult`, computed once and shared by every sink that publishes it.

`result_points` back-projects ``result.depth_mm`` with ``edge.runtime.depth.depth_to_points``
through the intrinsics of the geometry that produced it (``result.geometry``, else the given
fallback) at the profile's ``[points] stride``; the last cloud is cached, so the zenoh, ROS and
Foxglove sinks and the recorder do the work once per depth map.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from .depth import camera_matrix, depth_to_points

_lock = threading.Lock()
_last: tuple[Any, tuple, np.ndarray] | None = None


def result_points(result: Any, geometry: Any, stride: int) -> np.ndarray:
    """(N, 3) float32 metres in the optical frame for ``result`` (see module docstring)."""
    global _last
    k = camera_matrix(result.geometry if getattr(result, "geometry", None) is not None else geometry)
    key = (tuple(k.ravel()), int(stride))
    with _lock:
        if _last is not None and _last[0] is result and _last[1] == key:
            return _last[2]
    pts = depth_to_points(result.depth_mm, k, stride=stride)
    pts.setflags(write=False)
    with _lock:
        _last = (result, key, pts)
    return pts


def result_intrinsics(result: Any, geometry: Any) -> np.ndarray:
    """(3, 3) K of the geometry that produced ``result`` (else ``geometry``)."""
    return camera_matrix(result.geometry if getattr(result, "geometry", None) is not None else geometry)

"""Pictures the commands write for people to look at (colour-mapped, not data): depth, projector
columns and confidence."""

from __future__ import annotations

import numpy as np


def colorize_depth(depth_mm: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 BGR picture of an (H, W) uint16 depth map in mm (0 = invalid): TURBO over
    the 1st..99th percentile of the valid depths (near blue, far red), invalid pixels black."""
    import cv2

    valid = depth_mm > 0
    out = np.zeros(depth_mm.shape + (3,), np.uint8)
    if valid.any():
        lo, hi = np.percentile(depth_mm[valid], [1, 99])
        scaled = np.clip((depth_mm.astype(np.float32) - lo) / max(hi - lo, 1.0), 0, 1)
        out = cv2.applyColorMap((scaled * 255).astype(np.uint8), cv2.COLORMAP_TURBO)
        out[~valid] = 0
    return out


def column_image(column: np.ndarray, columns: int) -> np.ndarray:
    """(H, W) int32 columns (-1 invalid) -> (H, W, 3) uint8 BGR (turbo colour map, invalid black)."""
    import cv2

    scaled = np.clip(column.astype(np.float64) * (255.0 / max(columns - 1, 1)), 0, 255).astype(np.uint8)
    img = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)
    img[column < 0] = 0
    return img


def confidence_image(confidence: np.ndarray) -> np.ndarray:
    """(H, W) float32 in [0, 1] -> (H, W) uint8 0..255."""
    return np.clip(np.rint(confidence * 255.0), 0, 255).astype(np.uint8)

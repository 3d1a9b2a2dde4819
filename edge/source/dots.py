"""Random dot patterns and block matching of a dot image against the projector's reference pattern."""

from __future__ import annotations

import cv2
import numpy as np


def random_dots(width: int, height: int, *, density: float = 0.12, seed: int = 0) -> np.ndarray:
    """Random dot pattern: bool (height, width), each pixel lit with probability ``density``."""
    if not 0.0 < density < 1.0:
        raise ValueError(f"dot density must be in (0, 1), got {density}")
    if width < 1 or height < 1:
        raise ValueError(f"dot pattern size must be positive, got {width}x{height}")
    return np.random.default_rng(seed).random((height, width)) < density


def block_match(dot_image: np.ndarray, reference: np.ndarray, *, min_disparity: int, max_disparity: int,
                block_size: int = 11, blur_sigma: float = 0.8, uniqueness: int = 5) -> np.ndarray:
    """Disparity of a camera dot image against the projector reference by OpenCV StereoSGBM.

    dot_image: (H, W) camera image (any numeric; > 0 = dot).  reference: (H, W) projector pattern,
    rectified with the camera (row y of the camera sees row y of the projector, column ``x - d``).
    Returns float32 (H, W) disparity ``d = x_camera - column`` (pixels), NaN where no match.
    """
    cam = np.asarray(dot_image, np.float32)
    ref = np.asarray(reference, np.float32)
    if cam.shape != ref.shape or cam.ndim != 2:
        raise ValueError(f"dot image and reference must be equal (H, W), got {cam.shape} and {ref.shape}")
    if max_disparity <= min_disparity:
        raise ValueError(f"need max_disparity > min_disparity, got {min_disparity}..{max_disparity}")
    if block_size % 2 == 0 or block_size < 3:
        raise ValueError(f"block_size must be odd and >= 3, got {block_size}")

    def prep(img: np.ndarray) -> np.ndarray:
        img = (img > 0).astype(np.float32)
        if blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), blur_sigma)
        return np.clip(img * (255.0 / max(float(img.max()), 1e-6)), 0, 255).astype(np.uint8)

    num = int(np.ceil((max_disparity - min_disparity + 1) / 16.0)) * 16
    matcher = cv2.StereoSGBM_create(
        minDisparity=int(min_disparity), numDisparities=num, blockSize=int(block_size),
        P1=8 * block_size * block_size, P2=32 * block_size * block_size, uniquenessRatio=int(uniqueness),
        disp12MaxDiff=-1, speckleWindowSize=0, mode=cv2.STEREO_SGBM_MODE_SGBM,
    )
    raw = matcher.compute(prep(cam), prep(ref)).astype(np.float32) / 16.0
    raw[raw < min_disparity] = np.nan
    raw[raw > max_disparity] = np.nan
    return raw

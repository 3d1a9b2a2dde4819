"""Light-curtain pipeline (profile ``light-curtain``): one scan (a "slots" stack of L frames) ->
the curtain detection image -> a depth-like output.

The L slot frames are de-spread with the device's source code (`edge.source.matched_filter.despread`,
correlation threshold ``decoder.min_confidence``, minimum amplitude ``decoder.min_contrast`` of full
scale): a pixel is *detected* when its own laser's light passes the matched filter, i.e. a surface
lies on the scanned curtain (light of another device's laser, ambient light and noise are rejected).

Published (exactly like a column stack's output):

* depth: uint16 mm, the scanned curtain's depth ``focal_px * baseline_m / (d + doffs)`` at detected
  pixels, 0 elsewhere; the curtain of stack k has disparity `edge.device.curtain_disparity`
  (``CURTAINS`` curtains swept across the profile's disparity band, near to far, repeating);
* confidence: uint8, the matched-filter correlation (0..1 -> 0..255) at detected pixels, 0 elsewhere.
"""

from __future__ import annotations

import time

import numpy as np

from edge.device import DeviceModel

from .assembly import Stack
from .depth import confidence_to_u8, disparity_to_depth_mm
from .result import DepthResult


class CurtainPipeline:
    """See module docstring.  ``process(stack) -> DepthResult``; stats: ``curtain_detections``."""

    def __init__(self, profile) -> None:
        if profile.projector.kind != "line":
            raise ValueError(f"CurtainPipeline needs projector.kind = 'line', profile {profile.name!r} has "
                             f"{profile.projector.kind!r}")
        if profile.decoder.method != "curtain":
            raise ValueError(f"profile {profile.name!r}: a line projector is decoded by decoder.method = "
                             f"'curtain', got {profile.decoder.method!r}")
        self.profile = profile
        self.device = DeviceModel.from_profile(profile)
        self.source = self.device.source
        self.schedule = self.device.schedule
        self.geometry = profile.geometry
        self.full_scale = self.device.full_scale

    def warm_up(self) -> float:
        """Nothing to compile (the matched filter is numpy); returns 0."""
        return 0.0

    def detect(self, images: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(L, H, W) slot frames -> (detected bool (H, W), correlation float32 (H, W))."""
        p = self.profile
        min_amp = float(p.decoder.min_contrast) * self.full_scale
        if "0" not in self.source:  # uncoded laser: bright enough is a detection
            img = images.astype(np.float32).mean(axis=0)
            det = img >= min_amp
            return det, det.astype(np.float32)
        from edge.source.matched_filter import despread

        ds = despread(images, self.source, threshold=float(p.decoder.min_confidence), min_amplitude=min_amp)
        return ds.accepted[0], ds.correlation[0]

    def process(self, stack: Stack, masked_capture=None) -> DepthResult:
        t0 = time.perf_counter()
        ids = np.array([f.projector_frame for f in stack.frames], dtype=np.int64)
        if not np.array_equal(ids, self.schedule):
            raise ValueError(f"a curtain scan must follow the profile schedule of {self.schedule.size} slots, "
                             f"got ids {ids.tolist()[:8]}")
        images = np.stack([f.image for f in stack.frames])
        detected, corr = self.detect(images)
        d = self.device.curtain_disparity(stack.stack)
        disparity = np.where(detected, np.float64(d), np.nan)
        depth = disparity_to_depth_mm(disparity, self.geometry)
        x = np.arange(depth.shape[1], dtype=np.int32)[None, :]
        column = np.where(depth > 0, x - np.int32(d), np.int32(-1)).astype(np.int32)
        return DepthResult(
            stack=stack.stack, sequence=stack.first_sequence, timestamp_ns=stack.timestamp_ns,
            received_ns=stack.received_ns, depth_mm=depth, confidence=confidence_to_u8(corr, depth > 0),
            column=column, decode_s=time.perf_counter() - t0,
            stats={"curtain_detections": int(np.count_nonzero(depth))})

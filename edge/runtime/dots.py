"""Dot-projector depth: frame cameras (`DotsPipeline`) and event cameras (`EventDotsPipeline`).

Both produce one depth map per code period (a "slots" stack, `edge.sensors.base.slot_schedule`)
and end the same way: a dot image -> disparity by block matching against the reference
(`edge.source.dots.block_match`, OpenCV StereoSGBM over the profile's disparity band) -> depth
(`edge.runtime.depth.disparity_to_depth_mm`, uint16 mm, 0 = invalid).

Frame cameras (``oak-d-pro``): the L slot frames of the stack are de-spread
(`edge.source.matched_filter.despread`, threshold ``decoder.min_confidence``, minimum amplitude
``decoder.min_contrast`` of full scale) into the own-projector dot image; ambient light and foreign
projectors cancel.  The reference is the projector's dot pattern (`edge.device.DeviceModel.dot_pattern`)
for a simulated device (frames ``(H, W)``), or the de-spread right image for a stereo device (the
OAK in stereo mode: frames ``(H, 2W)``, left | right mono side by side).  Confidence: the block's dot support, the fraction of its pixels that
passed the matched filter relative to the projected dot density (clipped to [0, 1]).

Event cameras (``event-dots``): the events of the stack's L slices are checked (events outside their
slice's time window, or going back in time, are dropped and counted; events outside the sensor are
dropped and counted by the matched filter), matched-filtered with the device's code
(`edge.source.matched_filter.filter_events`, cosine threshold ``decoder.min_confidence``), and the
kept positive events of the period form the dot image.  Confidence: the block's fraction of events
the filter kept.  Counters go to `DepthResult.stats` (summed into the service status).

Everything is deterministic in the stack's frames / events, so `edge replay` reproduces the depth bit
for bit.  Call `process` from one thread (numba parallel kernels).
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from edge.device import DOT_DENSITY, DeviceModel, check_dot_profile

from .assembly import Stack
from .depth import confidence_to_u8, disparity_to_depth_mm
from .result import DepthResult

#: SGBM block size (pixels, odd)
BLOCK_SIZE = 11


def box_mean(image: np.ndarray, block: int = BLOCK_SIZE) -> np.ndarray:
    """float32 (H, W) mean of ``image`` over ``block`` x ``block`` windows (reflected borders)."""
    return cv2.blur(np.asarray(image, np.float32), (block, block), borderType=cv2.BORDER_REFLECT)


def disparity_to_column(disparity: np.ndarray) -> np.ndarray:
    """(H, W) float disparity (NaN invalid) -> int32 reference column ``rint(x - d)``, -1 invalid."""
    x = np.arange(disparity.shape[1], dtype=np.float64)[None, :]
    col = x - disparity.astype(np.float64)
    ok = np.isfinite(col) & (col >= 0)
    return np.where(ok, np.rint(np.where(ok, col, 0)), -1).astype(np.int32)


def count_image(events: np.ndarray, width: int, height: int, mask: np.ndarray | None = None,
                positive_only: bool = False) -> np.ndarray:
    """int32 (H, W) events per pixel (the ``mask``-selected ones; only p > 0 with ``positive_only``);
    events outside the sensor are ignored.  Same counts as `edge.source.events.event_frame`, by bincount."""
    sel = np.ones(events.size, bool) if mask is None else np.asarray(mask, bool).copy()
    if positive_only:
        sel &= events["p"] > 0
    x = events["x"].astype(np.int64)
    y = events["y"].astype(np.int64)
    sel &= (x < width) & (y < height)
    flat = np.bincount(y[sel] * width + x[sel], minlength=width * height)
    return flat.astype(np.int32).reshape(height, width)


class _SlotPipeline:
    """Shared set-up of the "slots" pipelines."""

    def __init__(self, profile, expected_kind: str) -> None:
        if profile.projector.kind != "dots":
            raise ValueError(f"{type(self).__name__} needs projector.kind = 'dots', profile {profile.name!r} "
                             f"has {profile.projector.kind!r}")
        if profile.decoder.method != "block-match":
            raise ValueError(f"profile {profile.name!r}: a dot projector is decoded by decoder.method = "
                             f"'block-match', got {profile.decoder.method!r}")
        check_dot_profile(profile)
        self.profile = profile
        self.device = DeviceModel.from_profile(profile)
        self.kind = expected_kind
        self.source = self.device.source
        self.source_length = self.device.source_length
        self.schedule = self.device.schedule
        self.geometry = profile.geometry
        self.full_scale = self.device.full_scale
        self.band = (int(profile.decoder.min_disparity), int(profile.decoder.max_disparity))
        if self.band[1] <= self.band[0]:
            raise ValueError(f"profile {profile.name!r}: block matching needs decoder.max_disparity > "
                             f"min_disparity, got {self.band[0]}..{self.band[1]}")

    def warm_up(self) -> float:
        """Nothing to compile (OpenCV block matching); the reference pattern is built in ``__init__``."""
        return 0.0

    def check_ids(self, stack: Stack) -> None:
        ids = np.array([f.projector_frame for f in stack.frames], dtype=np.int64)
        if not np.array_equal(ids, self.schedule):
            raise ValueError(f"stack frames must follow the profile schedule of {self.schedule.size} slots, "
                             f"got ids {ids.tolist()[:8]}")

    def match(self, dot_image: np.ndarray, reference: np.ndarray) -> np.ndarray:
        from edge.source.dots import block_match

        return block_match(dot_image, reference, min_disparity=self.band[0], max_disparity=self.band[1],
                           block_size=BLOCK_SIZE)

    def result(self, stack: Stack, disparity: np.ndarray, confidence: np.ndarray, t0: float,
               stats: dict[str, int] | None = None, dots: np.ndarray | None = None) -> DepthResult:
        """The `DepthResult` of a matched disparity (NaN invalid), with depth only where the block
        around the pixel holds at least one of the own dots (``dots``: the dot image matched, > 0 at a
        dot): block matching returns disparities in blocks without texture too (no light from
        the own projector: a dark scene, the projector off), and those are not measurements."""
        if dots is not None:
            supported = box_mean(np.asarray(dots) > 0) > np.float32(0.5 / BLOCK_SIZE**2)
            disparity = np.where(supported, disparity, np.nan)
        depth = disparity_to_depth_mm(disparity, self.geometry)
        return DepthResult(
            stack=stack.stack, sequence=stack.first_sequence, timestamp_ns=stack.timestamp_ns,
            received_ns=stack.received_ns, depth_mm=depth, confidence=confidence_to_u8(confidence, depth > 0),
            column=np.where(depth > 0, disparity_to_column(disparity), np.int32(-1)),
            decode_s=time.perf_counter() - t0, stats=dict(stats or {}))


class DotsPipeline(_SlotPipeline):
    """Frame-camera dot projector (see module docstring).  ``process(stack) -> DepthResult``."""

    def __init__(self, profile) -> None:
        super().__init__(profile, "dots")
        self.reference = self.device.dot_pattern().astype(np.float32)

    def dot_image(self, images: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(L, H, W') slot images -> (own dot amplitude float32 (H, W'), correlation float32 (H, W'))."""
        p = self.profile
        min_amp = float(p.decoder.min_contrast) * self.full_scale
        if "0" not in self.source:  # no spreading: dots = what stands out of the local mean
            img = images.astype(np.float32).mean(axis=0)
            local = box_mean(img, 2 * BLOCK_SIZE + 1)
            amp = np.where(img - local >= min_amp, img - local, 0).astype(np.float32)
            return amp, (amp > 0).astype(np.float32)
        from edge.source.matched_filter import despread

        ds = despread(images, self.source, threshold=float(p.decoder.min_confidence), min_amplitude=min_amp)
        return ds.frames[0], ds.correlation[0]

    def process(self, stack: Stack, masked_capture=None) -> DepthResult:
        t0 = time.perf_counter()
        self.check_ids(stack)
        images = np.stack([f.image for f in stack.frames])
        w, h = self.profile.camera.width, self.profile.camera.height
        if images.shape[1:] not in ((h, w), (h, 2 * w)):
            raise ValueError(f"dot frames must be ({h}, {w}) or ({h}, {2 * w}) (stereo: left | right), "
                             f"got {images.shape[1:]}")
        stereo = images.shape[2] == 2 * w
        amp, corr = self.dot_image(images)
        if stereo:
            left, reference, corr = amp[:, :w], amp[:, w:], corr[:, :w]
        else:
            left, reference = amp, self.reference
        disparity = self.match(left, reference)
        confidence = np.clip(box_mean(left > 0) / np.float32(DOT_DENSITY), 0.0, 1.0)
        return self.result(stack, disparity, confidence, t0, {"dot_pixels": int(np.count_nonzero(left))}, left)


class EventDotsPipeline(_SlotPipeline):
    """Event-camera dot projector (see module docstring).  ``process(stack) -> DepthResult``."""

    def __init__(self, profile) -> None:
        super().__init__(profile, "event-dots")
        if "0" not in self.source:
            raise ValueError(f"profile {profile.name!r}: an event sensor needs a source code with a 0 chip, "
                             f"got {self.source!r}")
        self.slot_us = self.device.slot_us
        self.guard_us = self.slot_us // 4
        self.reference = self.device.dot_pattern().astype(np.float32)

    def clean(self, slices) -> tuple[np.ndarray, dict[str, int]]:
        """Concatenate the slices' events, dropping (and counting) events outside their slice's window
        and events that go back in time against an earlier event of the stack."""
        from edge.source.events import EVENT_DTYPE

        parts, n_in, n_window = [], 0, 0
        for s in slices:
            ev = np.asarray(s.events)
            if ev.dtype != EVENT_DTYPE:
                ev = ev.astype(EVENT_DTYPE)
            n_in += ev.size
            t = ev["t"]
            inside = (t >= s.t_start_us) & (t < s.t_end_us)
            n_window += int(ev.size - np.count_nonzero(inside))
            parts.append(ev[inside])
        ev = np.concatenate(parts) if parts else np.empty(0, EVENT_DTYPE)
        order_ok = np.ones(ev.size, bool)
        if ev.size > 1:
            t = ev["t"]
            order_ok[1:] = t[1:] >= np.maximum.accumulate(t)[:-1]
        n_order = int(ev.size - np.count_nonzero(order_ok))
        if n_order:
            ev = ev[order_ok]
        return ev, {"events_in": n_in, "events_out_of_window": n_window, "events_out_of_order": n_order}

    def process(self, stack: Stack, masked_capture=None) -> DepthResult:
        from edge.source.matched_filter import filter_events

        t0 = time.perf_counter()
        self.check_ids(stack)
        slices = stack.frames
        if not all(hasattr(s, "events") for s in slices):
            raise ValueError("an event-dots stack must hold EventSlice records (events), got camera frames")
        w, h = self.profile.camera.width, self.profile.camera.height
        ev, stats = self.clean(slices)
        res = filter_events(ev, self.source, width=w, height=h, slot_us=self.slot_us,
                            t0_us=int(slices[0].t_start_us) + self.guard_us, guard_us=self.guard_us,
                            threshold=float(self.profile.decoder.min_confidence))
        stats["events_out_of_bounds"] = int(res.dropped_out_of_bounds)
        stats["events_kept"] = int(res.kept)
        dots = count_image(ev, w, h, res.keep, positive_only=True)
        disparity = self.match(dots, self.reference)
        kept = box_mean(count_image(ev, w, h, res.keep))
        total = box_mean(count_image(ev, w, h))
        confidence = np.divide(kept, total, out=np.zeros_like(total), where=total > 0)
        return self.result(stack, disparity, confidence, t0, stats, dots)

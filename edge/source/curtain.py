"""Light curtains with source-coded lasers (paper section 5, example 2).

A light-curtain device steps a line laser (projector column ``col``) and a line-sensor column (camera
column ``x``) together, one step per camera column, keeping ``x - col = d0``: the camera column sees
laser light only where a surface lies on the plane of disparity ``d0`` (the curtain).  The curtain
image is (H, steps): row y of step j is camera pixel (y, x_j).

A second device nearby (its laser at another baseline, scanning on its own clock) lights surfaces
that camera 1's column also sees: a false curtain at another depth.  With source codes each step lasts
L slots, every laser sends its code, and camera 1 keeps a pixel only when its L slot values pass the
matched filter (`edge.source.matched_filter.despread`) for its own code.

Model: camera-1 pixel intensity in a slot = albedo * (sum over lasers on in that slot, time-averaged
over the slot, of power * exp(-(col_k(y, x) - laser column)^2 / (2 w^2)) + ambient) + Gaussian noise
(read ``sigma_r`` and shot ``sigma_s``).  The own laser's column map is the scene's ground truth
(``scene.column``, shadows included); foreign lasers use the scene depth from their baseline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..codes.source import source_code
from ..sim import Geometry, Scene, make_scene
from ..triangulation import disparity_from_depth
from .matched_filter import DEFAULT_THRESHOLD, despread


@dataclass(frozen=True)
class CurtainDevice:
    """A line laser.  code: its source code (``"1"`` = uncoded, always on during a step);
    baseline_m: laser position along the camera-1 baseline; scan_offset_px: the laser is at column
    ``j - scan_offset_px`` in its step j; phase_slots: its clock offset against camera 1, in camera-1
    slots (may be fractional); power: laser level (white surface)."""

    code: str = "1"
    baseline_m: float = 0.10
    scan_offset_px: float = 0.0
    phase_slots: float = 0.0
    power: float = 1.0


@dataclass(frozen=True)
class CurtainConfig:
    width: int = 320
    height: int = 240
    scene: str = "steps"
    seed: int = 1
    curtain_depth_m: float = 0.93
    false_depth_m: float = 1.27
    second_baseline_m: float = 0.16
    line_width_px: float = 0.6
    ambient: float = 0.1
    sigma_r: float = 0.01
    sigma_s: float = 0.01
    detect_level: float = 0.15
    threshold: float = DEFAULT_THRESHOLD
    subsamples: int = 4

    def geometry(self) -> Geometry:
        f = 300.0 * self.width / 320.0
        return Geometry.default(self.width, self.height, focal_px=f, cx_projector=self.width / 2.0,
                                projector_width=self.width)


def _uncoded(code: str) -> bool:
    return code == "1"


def _device_bits(code: str) -> np.ndarray:
    return np.ones(1, np.uint8) if _uncoded(code) else source_code(code).bits


def curtain_slots(scene: Scene, devices: list[CurtainDevice], cfg: CurtainConfig, *, rng: np.random.Generator,
                  slots: int) -> np.ndarray:
    """Camera-1 slot frames (slots, H, steps) float32 for a scan with ``slots`` slots per step.

    devices[0] is the observer's own laser (uses ``scene.column``); the others light the scene from
    their baselines.  Device k at camera-1 time tau (in slots) is at its step
    ``floor((tau - phase) / L_k)`` and slot ``(tau - phase) mod L_k``.
    """
    g = scene.geometry
    h, w = scene.shape
    cols = [scene.column.astype(np.float64)]
    for dev in devices[1:]:
        z = scene.depth_m.astype(np.float64)
        cols.append(np.arange(w)[None, :] - disparity_from_depth(z, g.focal_px, dev.baseline_m, g.doffs))
    out = np.zeros((slots, h, w), np.float64)
    sub = (np.arange(cfg.subsamples) + 0.5) / cfg.subsamples
    x = np.arange(w)
    for k, dev in enumerate(devices):
        bits = _device_bits(dev.code)
        lk = bits.size
        colmap = cols[k]
        for s in range(slots):
            acc = np.zeros((h, w))
            for f in sub:
                tau = x * slots + s + f - dev.phase_slots  # (steps,) device time in its slots
                step = np.floor(tau / lk)
                on = bits[(np.floor(tau).astype(np.int64)) % lk].astype(np.float64)
                laser = step - dev.scan_offset_px  # laser column of device k
                u = colmap - laser[None, :]
                with np.errstate(invalid="ignore"):
                    line = np.exp(-0.5 * (u / cfg.line_width_px) ** 2)
                acc += np.nan_to_num(line) * on[None, :]
            out[s] += dev.power * acc / cfg.subsamples
    inten = scene.albedo[None].astype(np.float64) * (out + cfg.ambient)
    noise = np.sqrt(cfg.sigma_r**2 + cfg.sigma_s**2 * inten) * rng.standard_normal(inten.shape)
    return (inten + noise).astype(np.float32)


@dataclass(frozen=True)
class CurtainResult:
    """detected: bool (H, steps) curtain image; truth: bool (H, steps) own-curtain ground truth;
    amplitude: float32 (H, steps) intensity (uncoded) or de-spread amplitude (coded)."""

    detected: np.ndarray
    truth: np.ndarray
    amplitude: np.ndarray
    codes: tuple[str, ...]

    def rates(self) -> dict:
        neg = ~self.truth
        fp = int((self.detected & neg).sum())
        fn = int((~self.detected & self.truth).sum())
        return {
            "false_detections": fp, "false_detection_rate": fp / max(1, int(neg.sum())),
            "missed_detections": fn, "missed_detection_rate": fn / max(1, int(self.truth.sum())),
            "detections": int(self.detected.sum()), "truth": int(self.truth.sum()),
        }


def run_curtain(cfg: CurtainConfig, codes: tuple[str, ...] = ("1", "1"), *, phase_slots: float | tuple = 0.0,
                seed: int = 0) -> CurtainResult:
    """Device 1 scans the curtain at ``curtain_depth_m``; devices 2.. are placed so that device 2's
    laser forms a false curtain at ``false_depth_m`` in camera 1 (further devices: further out).

    codes: one per device (``"1"`` = uncoded).  All coded devices must share one length L.
    phase_slots: clock offset of devices 2.. against device 1 (camera-1 slots), one value or one per device.
    """
    if len(codes) < 1:
        raise ValueError("need at least one device code")
    lengths = {len(c) for c in codes}
    if len(lengths) != 1:
        raise ValueError(f"all curtain devices must use codes of one length, got {codes}")
    L = lengths.pop()
    g = cfg.geometry()
    scene = make_scene(cfg.scene, cfg.width, cfg.height, seed=cfg.seed, geometry=g)
    d0 = disparity_from_depth(cfg.curtain_depth_m, g.focal_px, g.baseline_m, g.doffs)
    phases = (phase_slots,) * (len(codes) - 1) if np.isscalar(phase_slots) else tuple(phase_slots)
    devices = [CurtainDevice(codes[0], g.baseline_m, d0, 0.0)]
    for i, c in enumerate(codes[1:]):
        b = cfg.second_baseline_m * (1 + 0.5 * i)
        off = disparity_from_depth(cfg.false_depth_m, g.focal_px, b, g.doffs)
        devices.append(CurtainDevice(c, b, off, float(phases[i]) * 1.0))
    rng = np.random.default_rng(seed)
    slots = curtain_slots(scene, devices, cfg, rng=rng, slots=L)
    # ground truth: own laser alone, noise-free, would pass the detection level
    x = np.arange(cfg.width)
    u = scene.column.astype(np.float64) - (x - d0)[None, :]
    with np.errstate(invalid="ignore"):
        own = np.nan_to_num(np.exp(-0.5 * (u / cfg.line_width_px) ** 2)) * scene.albedo
    truth = own >= cfg.detect_level
    if _uncoded(codes[0]):
        amp = slots[0] - scene.albedo * cfg.ambient  # ambient known per pixel (a laser-off frame)
        detected = amp >= cfg.detect_level
    else:
        ds = despread(slots, codes[0], threshold=cfg.threshold, min_amplitude=cfg.detect_level)
        amp, detected = ds.frames[0], ds.accepted[0]
    return CurtainResult(detected, truth, amp.astype(np.float32), tuple(codes))

"""Light curtains with source-coded lasers (paper section 5, example 2).

A light-curtain device steps a line laser (projector column ``col``) and a line-sensor column (camera
column ``x``) together, one step per camera column, keeping ``x - col = d0``: the camera column sees
laser light only where a surface lies on the plane of disparity ``d0`` (the curtain).  The curtain
image is (H, steps): row y of step j is camera pixel (y, x_j).

A second device nearby (its laser at another baseline, scanning on its own clock) lights surfaces
that camera 1's column also sees: a false curtain at another depth.  With source codes each step lasts
L slots, every laser sends its code, and camera 1 keeps a pixel only when its L slot values pass the
matched filter (`edge.source.matched_filter.despread`) for its own code.

Pure functions here: `curtain_slots` (the slot frames), `curtain_detect` (the detection) and
`curtain_truth` (the ground truth); the scenario runner is `edge.eval.curtain.run_curtain`.

Model: camera-1 pixel intensity in a slot = albedo * (sum over lasers on in that slot, time-averaged
over the slot, of power * exp(-(col_k(y, x) - laser column)^2 / (2 w^2)) + ambient) + Gaussian noise
(read ``sigma_r`` and shot ``sigma_s``).  The own laser's column map is the scene's ground truth
(``scene.column``, shadows included); foreign lasers use the scene depth from their baseline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..codes.source import source_code
from ..sim import Geometry, Scene
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
        return Geometry.projector_as_wide(self.width, self.height)


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


def curtain_detect(slots: np.ndarray, code: str, albedo: np.ndarray, cfg: CurtainConfig) -> tuple[np.ndarray, np.ndarray]:
    """Camera-1 detection of its own curtain: (amplitude float32 (H, steps), detected bool (H, steps)).

    slots: (L, H, steps) slot frames of `curtain_slots`; code: the own laser's code (``"1"`` =
    uncoded).  Uncoded: the first slot minus the known ambient ``albedo * cfg.ambient`` (a
    laser-off frame) must reach ``cfg.detect_level``; coded: the matched filter (`despread`,
    ``cfg.threshold``, amplitude at least ``cfg.detect_level``) for ``code``.
    """
    if _uncoded(code):
        amp = slots[0] - albedo * cfg.ambient  # ambient known per pixel (a laser-off frame)
        detected = amp >= cfg.detect_level
    else:
        ds = despread(slots, code, threshold=cfg.threshold, min_amplitude=cfg.detect_level)
        amp, detected = ds.frames[0], ds.accepted[0]
    return amp.astype(np.float32), detected


def curtain_truth(scene: Scene, d0: float, cfg: CurtainConfig) -> np.ndarray:
    """(H, steps) bool: pixels where the own laser alone, noise-free, reaches ``cfg.detect_level``
    on the curtain of disparity ``d0`` (the ground truth of a scan)."""
    x = np.arange(scene.shape[1])
    u = scene.column.astype(np.float64) - (x - d0)[None, :]
    with np.errstate(invalid="ignore"):
        own = np.nan_to_num(np.exp(-0.5 * (u / cfg.line_width_px) ** 2)) * scene.albedo
    return own >= cfg.detect_level

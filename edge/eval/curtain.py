"""Evaluation of two light curtains with and without source codes (paper section 5, example 2):
`run_curtain` places the devices of a scenario and scans once; `CurtainResult.rates` gives the
false and missed detection rates (``edge source curtain-demo``, ``tools/eval_source.py``).

The model is `edge.source.curtain` (`CurtainConfig`, `curtain_slots`, `curtain_detect`,
`curtain_truth`); this module only builds the scene and the devices and counts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sim import make_scene
from ..source.curtain import CurtainConfig, CurtainDevice, curtain_detect, curtain_slots, curtain_truth
from ..triangulation import disparity_from_depth


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
    amp, detected = curtain_detect(slots, codes[0], scene.albedo, cfg)
    return CurtainResult(detected, curtain_truth(scene, d0, cfg), amp, tuple(codes))

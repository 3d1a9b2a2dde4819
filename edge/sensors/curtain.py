"""Simulated light curtain (profile ``light-curtain``): a line laser and a line camera scanned
together, emulated column by column with `edge.source.curtain.curtain_slots`.

One stack is one scan of one curtain: every camera column x is one scan step, in which the laser
lights projector column ``x - d`` (d = the curtain's disparity) during the L slots of the device's
source code.  The camera frame of slot j holds, in column x, the line reading of step x during
slot j, so a scan is L frames (H, W) in the "slots" layout.  Successive scans sweep
`CURTAINS` curtains across the profile's disparity band (`edge.device.curtain_disparity`), near to far.
``interference=True`` adds a second, unsynchronised curtain device with code `INTERFERER_CODE`
whose laser forms a false curtain that the matched filter rejects.

Intensities: albedo * (laser power ``sim.projector`` + ambient ``sim.ambient``) plus the camera's
read and shot noise, quantised to ``camera.bits``.
"""

from __future__ import annotations

import numpy as np

from edge.device import CURTAINS, curtain_disparities, curtain_disparity, full_scale  # noqa: F401  (sweep plan re-exported)
from edge.triangulation import depth_from_disparity, disparity_from_depth

from .base import SensorInfo, slot_schedule
from .sim import PacedSensor, sim_geometry
#: the interfering device's code (a shifted 1010 square wave against the profile's 1100)
INTERFERER_CODE = "0101"
#: laser line width (Gaussian sigma, projector columns)
LINE_WIDTH_PX = 0.6


class CurtainSimSensor(PacedSensor):
    """Simulated light-curtain device (see module docstring).  ``poses`` is rounded up to a multiple
    of `CURTAINS` so that a cached scan always belongs to the curtain its stack id names."""

    def __init__(self, profile, *, stacks: int | None = None, max_speed: bool = False, poses: int = 0,
                 first_stack: int = 0, interference: bool = False, room=None) -> None:
        if profile.projector.kind != "line":
            raise ValueError(f"the curtain sim sensor needs projector.kind = 'line', profile {profile.name!r} "
                             f"has {profile.projector.kind!r}")
        src = profile.code.source or "1"
        L = len(src)
        cam = profile.camera
        self.code = src
        self.interference = bool(interference)
        from .room_model import RoomLight

        self.room = RoomLight(profile, room) if room is not None else None
        self.info = SensorInfo(
            name="sim-curtain", width=cam.width, height=cam.height, bits=cam.bits,
            fps=0.0 if max_speed else cam.rate_hz, n_code_frames=1, source_length=L, layout="slots",
            metadata={"backend": "sim", "projector": "line", "scene": profile.sim.scene,
                      "seed": str(profile.sim.seed), "interference": str(self.interference)})
        self.schedule = slot_schedule(L)
        self.geometry = sim_geometry(profile)
        poses = -(-int(poses) // CURTAINS) * CURTAINS if poses > 0 else 0
        self._init_stream(profile, stacks=stacks, max_speed=max_speed, poses=poses, first_stack=first_stack)

    def _devices(self, stack: int) -> list:
        from edge.source.curtain import CurtainDevice

        g = self.geometry
        power = float(self.profile.sim.projector)
        code = self.room.own_code() if self.room is not None else self.code
        devices = [CurtainDevice(code, g.baseline_m, float(curtain_disparity(self.profile, stack)), 0.0, power)]
        if self.room is not None:
            # every other member of the room: its laser from its baseline, scanning its own curtain
            # (half a sweep away from mine), at its room-clock offset (fractional slots) and power
            t0 = float(stack) * self.info.width * len(self.code)
            for k, f in enumerate(self.room.foreign()):
                b = f.baseline_factor * g.baseline_m
                d_f = curtain_disparity(self.profile, stack + CURTAINS // 2 + k)
                z_f = float(depth_from_disparity(d_f, g.focal_px, g.baseline_m, g.doffs))
                devices.append(CurtainDevice(f.code, b, disparity_from_depth(z_f, g.focal_px, b, g.doffs),
                                             f.offset_at(t0) % len(f.code), power * f.power))
        if self.interference:
            # a second device at 1.6x the baseline, its laser crossing the scene half a sweep away
            b2 = 1.6 * g.baseline_m
            d_false = curtain_disparity(self.profile, stack + CURTAINS // 2)
            z_false = float(depth_from_disparity(d_false, g.focal_px, g.baseline_m, g.doffs))
            devices.append(CurtainDevice(INTERFERER_CODE, b2, disparity_from_depth(z_false, g.focal_px, b2, g.doffs),
                                         0.5, power))
        return devices

    def _render(self, stack: int, rng: np.random.Generator) -> np.ndarray:
        """(L, H, W) quantised slot frames of the scan of ``stack``."""
        from edge.source.curtain import CurtainConfig, curtain_slots

        cam = self.profile.camera
        scene = self.scene(stack)
        cfg = CurtainConfig(width=cam.width, height=cam.height, line_width_px=LINE_WIDTH_PX,
                            ambient=float(self.profile.sim.ambient), sigma_r=cam.sigma_r, sigma_s=cam.sigma_s)
        slots = curtain_slots(scene, self._devices(stack), cfg, rng=rng, slots=len(self.code))
        levels = int(full_scale(cam.bits))
        q = np.clip(np.rint(slots.astype(np.float64) * levels), 0, levels)
        return q.astype(np.uint8 if cam.bits == 8 else np.uint16)

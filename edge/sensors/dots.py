"""Simulated dot-projector sensor (frame camera): the profile's scene lit by a random-dot pattern
that the projector switches on and off by the device's source code.

A stack is the "slots" layout (`edge.sensors.base.slot_schedule`): projector frame 0 (the dot
pattern) in the L slots of ``code.source``; slot j shows the pattern when chip j is 1 and nothing
when it is 0.  `edge.sim.capture` forms the images (eq. 1: ambient + projector light through the
scene's projector-column map, noise, ADC) with the profile's noise figures, one seeded RNG per
stack.  The projector sits where the profile's geometry puts it (for ``oak-d-pro`` that is the
right camera: baseline 75 mm, doffs 0), so the de-spread camera image block-matches against the
projector's pattern (`edge.device.dot_pattern`) exactly as a left image against a right one.
"""

from __future__ import annotations

import numpy as np

from edge.device import DOT_DENSITY, DeviceModel, check_dot_profile, dot_pattern  # noqa: F401  (re-exported)

from .base import SensorInfo
from .sim import PacedSensor, sim_camera, sim_geometry

#: per-slot exposure (edge.sim relative units): one slot carries projector + ambient light once
SLOT_EXPOSURE = 1.0


def source_bits(profile) -> np.ndarray:
    """float32 (L,) on/off chips of the profile's source code ([1] without one)."""
    src = profile.code.source or "1"
    return np.array([c == "1" for c in src], dtype=np.float32)


class DotsSimSensor(PacedSensor):
    """Simulated dot projector + mono camera for a 'dots' profile (see module docstring).

    stacks / max_speed / poses / first_stack: as `edge.sensors.sim.SimSensor`.
    """

    def __init__(self, profile, *, stacks: int | None = None, max_speed: bool = False, poses: int = 0,
                 first_stack: int = 0, room=None) -> None:
        if room is not None:
            raise ValueError(f"profile {profile.name!r}: the room simulator covers event-dots, light-curtain and "
                             "column (DLP) profiles; a frame-camera dot sensor cannot join a simulated room yet")
        if profile.projector.kind != "dots":
            raise ValueError(f"the dots sim sensor needs projector.kind = 'dots', profile {profile.name!r} has "
                             f"{profile.projector.kind!r}")
        check_dot_profile(profile)
        bits = source_bits(profile)
        L = bits.size
        cam = profile.camera
        self.info = SensorInfo(
            name="sim-dots", width=cam.width, height=cam.height, bits=cam.bits,
            fps=0.0 if max_speed else cam.rate_hz, n_code_frames=1, source_length=L, layout="slots",
            metadata={"backend": "sim", "projector": "dots", "scene": profile.sim.scene,
                      "seed": str(profile.sim.seed), "dot_density": str(DOT_DENSITY)})
        model = DeviceModel.from_profile(profile)
        self.schedule = model.schedule
        self.pattern = model.dot_pattern()
        self.projector_frames = (self.pattern[None].astype(np.float32) * bits[:, None, None])  # (L, Hp, Wp)
        self.geometry = sim_geometry(profile)
        self.camera = sim_camera(profile)
        self._init_stream(profile, stacks=stacks, max_speed=max_speed, poses=poses, first_stack=first_stack)

    def _render(self, stack: int, rng: np.random.Generator) -> np.ndarray:
        """(L, H, W) camera images of the L slots of ``stack``."""
        from edge.sim import capture

        return capture(self.scene(stack), self.projector_frames, self.camera, rng=rng, exposure=SLOT_EXPOSURE)

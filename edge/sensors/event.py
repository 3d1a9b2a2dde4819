"""Event backend: the event-sensor simulator driving the event-camera SL profile (``event-dots``).

The device's dot projector (pattern `edge.device.dot_pattern`) switches on and off by the
device's source code, one chip per slot of ``slot_us = 1e6 / projector.rate_hz`` microseconds (the
profile's camera rate must equal it: one time slice per slot).  An optional interfering device
(`edge.source.event_sl.Interferer`: another dot projector at another baseline with its own code,
slot length and phase, by default a plain ``10`` square wave) adds foreign events.  The scene is
the profile's moving `edge.sim` scene; the DVS model is `edge.source.events.simulate_events`
(log-intensity thresholds, refractory period, latency, jitter, background activity).

Stream layout ("slots", `edge.sensors.base.slot_schedule`): stack k is code period k; its L
`EventSlice` records are the slots' time windows on the sensor clock (microseconds)::

    period start   T_k = (k + 1) * P            (P = L * slot_us; the clock starts one period in)
    slice j        [T_k + offset + j * slot_us, T_k + offset + (j + 1) * slot_us)
    offset         latency_us - slot_us // 4   (own edges arrive latency_us after the slot start;
                                                the matched filter's guard is slot_us // 4)

so that `edge.source.matched_filter.filter_events` with ``t0_us = t_start(slice 0) + slot_us // 4``
bins every event of the stack into period 0 and slice j into slot j.  Each period is simulated on
its own, from a pre-roll slot (the previous period's last chip) so that the first edge fires; its
events outside the stack's window are cut.  Per-pixel threshold mismatch is drawn per stack (the
simulator takes one RNG).  Events are int64 microseconds of the sensor clock; ``timestamp_ns`` of a
slice is the host time it was delivered.
"""

from __future__ import annotations

import time

import numpy as np

from edge.device import DOT_DENSITY, check_dot_profile, dot_pattern, slot_us  # noqa: F401  (slot_us re-exported)

from .base import EventSlice, SensorInfo, slot_schedule
from .sim import PacedSensor, sim_geometry


def window_offset_us(latency_us: int, slot: int) -> int:
    """Start of slice 0 relative to the period start (see module docstring)."""
    return int(latency_us) - int(slot) // 4


class EventSimSensor(PacedSensor):
    """Simulated event camera + source-coded dot projector (see module docstring).

    interference: add the default `Interferer` (or pass one).  sensor: `EventSensor` keyword
    overrides (contrast, latency_us, jitter_us, background_rate_hz ...).  stacks / max_speed /
    poses / first_stack: as `edge.sensors.sim.SimSensor`.
    """

    def __init__(self, profile, *, stacks: int | None = None, max_speed: bool = False, poses: int = 0,
                 first_stack: int = 0, interference=False, sensor: dict | None = None, room=None) -> None:
        from edge.source.event_sl import Interferer
        from edge.source.events import EventSensor

        if profile.projector.kind != "dots":
            raise ValueError(f"the event sensor needs projector.kind = 'dots', profile {profile.name!r} has "
                             f"{profile.projector.kind!r}")
        check_dot_profile(profile)
        src = profile.code.source or "10"
        if "0" not in src:
            raise ValueError(f"an event sensor sees only changes: code.source needs a 0 chip, got {src!r}")
        self.slot_us = slot_us(profile)
        if abs(1e6 / profile.camera.rate_hz - self.slot_us) >= 1.0:
            raise ValueError(f"profile {profile.name!r}: the event sensor delivers one slice per projector slot, "
                             f"expected camera.rate_hz = projector.rate_hz = {profile.projector.rate_hz:g}, "
                             f"got {profile.camera.rate_hz:g}")
        self.bits = np.array([c == "1" for c in src], dtype=np.uint8)
        L = self.bits.size
        cam = profile.camera
        self.dvs = EventSensor(cam.width, cam.height, **(sensor or {}))
        self.interferer = (Interferer() if interference is True else interference) or None
        from .room_model import RoomLight

        self.room = RoomLight(profile, room) if room is not None else None
        self._interferers = [self.interferer] if self.interferer is not None else []
        self.offset_us = window_offset_us(self.dvs.latency_us, self.slot_us)
        self.info = SensorInfo(
            name="event", width=cam.width, height=cam.height, bits=cam.bits,
            fps=0.0 if max_speed else cam.rate_hz, n_code_frames=1, source_length=L, layout="slots",
            metadata={"backend": "event", "projector": "dots", "scene": profile.sim.scene,
                      "seed": str(profile.sim.seed), "slot_us": str(self.slot_us),
                      "latency_us": str(self.dvs.latency_us),
                      "interferer": repr(self.interferer) if self.interferer else "none"})
        self.schedule = slot_schedule(L)
        self.geometry = sim_geometry(profile)
        self.pattern = dot_pattern(profile)
        self._e_own = None
        self._e_foreign = None
        self._init_stream(profile, stacks=stacks, max_speed=max_speed, poses=poses, first_stack=first_stack)

    @property
    def period_us(self) -> int:
        return int(self.slot_us * self.bits.size)

    def period_start_us(self, stack: int) -> int:
        return (int(stack) + 1) * self.period_us

    def _irradiance(self, scene):
        from edge.sim import CameraModel, projector_irradiance
        from edge.source.dots import random_dots
        from edge.source.event_sl import foreign_irradiance

        e_own = projector_irradiance(scene, self.pattern[None].astype(np.float32), CameraModel())[0]
        e_f = []
        for i in self._interferers:
            dots = random_dots(self.info.width, self.info.height, density=i.dot_density, seed=i.seed)
            e_f.append(foreign_irradiance(scene, dots, i.baseline_m))
        return e_own, e_f

    def _room_interferers(self, stack: int) -> list:
        """The interferers of this stack: ``interference`` and every other member of the room (its
        code, its slot length from the room clock's drift, its offset, power and dot pattern)."""
        from edge.source.event_sl import Interferer

        out = [self.interferer] if self.interferer is not None else []
        if self.room is not None:
            self.bits = np.array([c == "1" for c in self.room.own_code()], dtype=np.uint8)
            t0 = float(self.period_start_us(stack)) / self.slot_us
            for f in self.room.foreign():
                out.append(Interferer(code=f.code, slot_us=self.slot_us * (1.0 + f.drift),
                                      phase_us=(f.offset_at(t0) % len(f.code)) * self.slot_us,
                                      baseline_m=f.baseline_factor * self.geometry.baseline_m,
                                      power=float(self.profile.sim.projector) * f.power, dot_density=DOT_DENSITY,
                                      seed=f.seed))
        return out

    def _render(self, stack: int, rng: np.random.Generator) -> list[np.ndarray]:
        """L event arrays (EVENT_DTYPE, ``t`` relative to the period start T_k) of the slices of ``stack``."""
        from edge.source.events import simulate_events

        scene = self.scene(stack)
        self._interferers = self._room_interferers(stack)
        e_own, e_fs = self._irradiance(scene)
        slot, L, P = self.slot_us, self.bits.size, self.period_us
        t_k = self.period_start_us(stack)
        start, end = t_k - slot, t_k + P  # pre-roll slot, then the period
        times = [t_k + slot * np.arange(-1, L, dtype=np.int64)]
        for i in self._interferers:
            m = np.arange(np.floor((start - i.phase_us) / i.slot_us), np.ceil((end - i.phase_us) / i.slot_us) + 1)
            edges = np.floor(i.phase_us + m * i.slot_us).astype(np.int64)
            times.append(edges[(edges > start) & (edges < end)])
        t = np.unique(np.concatenate(times))
        own = self.bits[((t - t_k) // slot) % L].astype(np.float32)
        amb, power = np.float32(self.profile.sim.ambient), np.float32(self.profile.sim.projector)
        albedo = scene.albedo.astype(np.float32)
        inten = albedo[None] * (power * own[:, None, None] * e_own[None] + amb)
        for i, e_f in zip(self._interferers, e_fs):
            fbits = np.array([c == "1" for c in i.code], dtype=np.float64)
            s_f = fbits[np.floor((t - i.phase_us) / i.slot_us).astype(np.int64) % fbits.size].astype(np.float32)
            inten += (albedo * np.float32(i.power) * e_f)[None] * s_f[:, None, None]
        events = simulate_events(inten, t, self.dvs, rng=rng, end_us=int(end))
        w0 = t_k + self.offset_us
        bounds = w0 + slot * np.arange(L + 1, dtype=np.int64)
        idx = np.searchsorted(events["t"], bounds, side="left")
        out = []
        for j in range(L):
            ev = events[idx[j]:idx[j + 1]].copy()
            ev["t"] -= t_k
            out.append(ev)
        return out

    def _record(self, payload: np.ndarray, position: int, stack: int, sequence: int) -> EventSlice:
        t_k = self.period_start_us(stack)
        ev = payload.copy()
        ev["t"] += t_k
        t0 = t_k + self.offset_us + position * self.slot_us
        return EventSlice(ev, sequence, time.time_ns(), float(self.slot_us), int(self.schedule[position]), stack,
                          t0, t0 + self.slot_us)

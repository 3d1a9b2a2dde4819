"""Frame sources for the service: ``sim`` (default), ``replay`` (MCAP), ``oak`` (depthai v3), ``event``.

Every backend follows `edge.sensors.base.Sensor` and reports `Frame` records (image, sequence,
timestamp_ns, exposure_us, projector_frame, stack); `open_sensor` builds one from a profile.
"""

from __future__ import annotations

from typing import Any

from .base import (BLACK, WHITE, EndOfStream, Frame, MaskedCapture, ProjectorFrame, Sensor, SensorInfo,
                   parse_projector_frame, projector_frame_id, stack_schedule)

BACKENDS = ("sim", "replay", "oak", "event")


def open_sensor(profile, backend: str | None = None, *, replay_path: str | None = None, max_speed: bool = False,
                stacks: int | None = None, poses: int = 0, **options: Any) -> Sensor:
    """The backend named ``backend`` (default ``profile.sensor.backend``) configured from ``profile``.

    replay_path: MCAP file for ``replay`` (default ``profile.sensor.replay_path``); max_speed: no
    real-time pacing (sim, replay); stacks: end after this many stacks (sim); poses: sim pre-rendered
    motion poses (0 = live).
    """
    backend = backend or profile.sensor.backend
    if backend == "sim":
        from .sim import SimSensor

        return SimSensor(profile, stacks=stacks, max_speed=max_speed, poses=poses)
    if backend == "replay":
        from .replay import ReplaySensor

        path = replay_path or profile.sensor.replay_path
        if not path:
            raise ValueError("the replay sensor needs a recording: expected --replay FILE or sensor.replay_path, got none")
        return ReplaySensor(path, max_speed=max_speed or profile.sensor.replay_speed == "max")
    if backend == "oak":
        from .oak import OakSensor

        return OakSensor(profile, **options)
    if backend == "event":
        raise ValueError(
            "sensor backend 'event' is not wired into the service yet (event SL runs offline through "
            "edge.source.event_sl); expected one of sim, replay, oak")
    raise ValueError(f"unknown sensor backend {backend!r}; expected one of {', '.join(BACKENDS)}")


__all__ = ["BACKENDS", "BLACK", "WHITE", "EndOfStream", "Frame", "MaskedCapture", "ProjectorFrame", "Sensor",
           "SensorInfo", "open_sensor", "parse_projector_frame", "projector_frame_id", "stack_schedule"]

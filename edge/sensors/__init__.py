"""Frame sources for the service: ``sim`` (default), ``replay`` (MCAP), ``oak`` (depthai v3), ``event``.

Every backend follows `edge.sensors.base.Sensor` and reports `Frame` records (image, sequence,
timestamp_ns, exposure_us, projector_frame, stack); `open_sensor` builds one from a profile.
"""

from __future__ import annotations

import importlib

from typing import Any

from .base import (BLACK, WHITE, EndOfStream, EventSlice, Frame, MaskedCapture, ProjectorFrame, Sensor, SensorInfo,
                   layout_schedule, parse_projector_frame, projector_frame_id, slot_schedule, stack_schedule)

BACKENDS = ("sim", "replay", "oak", "event")


def open_sensor(profile, backend: str | None = None, *, replay_path: str | None = None, max_speed: bool = False,
                stacks: int | None = None, poses: int = 0, interference: bool = False, first_stack: int = 0,
                room: Any = None, **options: Any) -> Sensor:
    """The backend named ``backend`` (default ``profile.sensor.backend``) configured from ``profile``.

    replay_path: MCAP file for ``replay`` (default ``profile.sensor.replay_path``); max_speed: no
    real-time pacing (sim, event, replay); stacks: end after this many stacks (sim, event); poses:
    pre-rendered motion poses (0 = live); first_stack: id (scene time) of the first simulated
    stack; interference: the simulated event / curtain device gets an
    unsynchronised second device next to it; room: the room claim (`edge.io.room.RoomClaim` or
    `edge.sensors.room_model.StaticRoom`): the simulated sensors render every other member's light
    (`edge.sensors.room_model`).

    ``sim`` picks the simulator that fits the profile's projector: `SimSensor` (columns),
    `DotsSimSensor` (dots; a stand-in for the OAK's IR dot projector), `CurtainSimSensor` (line);
    for an event profile (pipeline kind ``event-dots``, `edge.device.pipeline_kind`) ``sim`` and ``event`` both mean
    `EventSimSensor`.
    """
    from edge.device import pipeline_kind

    backend = backend or profile.sensor.backend
    kind = profile.projector.kind
    if backend == "sim" and pipeline_kind(profile) == "event-dots":
        backend = "event"
    if backend == "sim":
        if kind == "dots":
            from .dots import DotsSimSensor

            return DotsSimSensor(profile, stacks=stacks, max_speed=max_speed, poses=poses, first_stack=first_stack,
                                 room=room)
        if kind == "line":
            from .curtain import CurtainSimSensor

            return CurtainSimSensor(profile, stacks=stacks, max_speed=max_speed, poses=poses,
                                    first_stack=first_stack, interference=interference, room=room)
        from .sim import SimSensor

        return SimSensor(profile, stacks=stacks, max_speed=max_speed, poses=poses, first_stack=first_stack,
                         room=room)
    if backend == "replay":
        # the replay backend reads MCAP, so it lives with the recordings in edge.io (above the
        # sensors); the factory names it, as the pipeline registry names its classes
        ReplaySensor = importlib.import_module("edge.io.replay_sensor").ReplaySensor
        path = replay_path or profile.sensor.replay_path
        if not path:
            raise ValueError("the replay sensor needs a recording: expected --replay FILE or sensor.replay_path, got none")
        return ReplaySensor(path, max_speed=max_speed or profile.sensor.replay_speed == "max")
    if backend == "oak":
        from .oak import OakSensor

        if options.get("pipeline") is None:
            require_oak_device()
        return OakSensor(profile, **options)
    if backend == "event":
        from .event import EventSimSensor

        return EventSimSensor(profile, stacks=stacks, max_speed=max_speed, poses=poses,
                              first_stack=first_stack, interference=interference, room=room)
    raise ValueError(f"unknown sensor backend {backend!r}; expected one of {', '.join(BACKENDS)}")


def require_oak_device() -> None:
    """ValueError (one line) when depthai sees no OAK device, before any pipeline is built (a
    device-less start used to fail deep inside ``start()`` after warm-up, with a traceback)."""
    try:
        import depthai as dai
    except ImportError as exc:
        raise ValueError(f"sensor oak: depthai is not installed ({exc})") from None
    try:
        devices = dai.Device.getAllAvailableDevices()
    except Exception as exc:  # depthai's own failure to enumerate: still one line
        raise ValueError(f"sensor oak: cannot list OAK devices ({type(exc).__name__}: {exc})") from None
    if not devices:
        raise ValueError("sensor oak: no OAK device found (depthai lists none): plug one in (in a container, "
                         "pass /dev/bus/usb through) or choose another sensor, e.g. --sensor sim")


__all__ = ["BACKENDS", "require_oak_device", "BLACK", "WHITE", "EndOfStream", "EventSlice", "Frame", "layout_schedule", "slot_schedule", "MaskedCapture", "ProjectorFrame", "Sensor",
           "SensorInfo", "open_sensor", "parse_projector_frame", "projector_frame_id", "stack_schedule"]

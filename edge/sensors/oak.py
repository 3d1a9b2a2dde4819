"""Luxonis OAK-D Pro through depthai v3: mono camera frames, IR emitters on the source-code schedule.

Pipeline (depthai 3.x API, checked by introspection of depthai 3.12)::

    pipeline = dai.Pipeline()                                   # implicit device
    cam = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_B)
    queue = cam.requestOutput((W, H), dai.ImgFrame.Type.GRAY8, fps=rate).createOutputQueue(...)
    pipeline.start()
    device = pipeline.getDefaultDevice()
    device.setIrLaserDotProjectorIntensity(x) / device.setIrFloodLightIntensity(x)   # 0..1

Each `dai.ImgFrame` becomes a `Frame` (`frame_from_imgframe`): ``getFrame()`` (copied),
``getSequenceNum()``, ``getTimestamp()`` (host-synchronised steady clock, mapped to wall-clock ns),
``getExposureTime()`` (microseconds).  The projector frame of a camera frame follows from its
sequence number: position ``(seq - seq0) % frames_per_stack`` of the stack schedule, stack id
``(seq - seq0) // frames_per_stack``; so a lost frame leaves a hole that the assembler drops.

Emitters: depthai has no per-frame emitter API; the host switches the dot projector (and
optionally the flood light) when frame ``s`` arrives, for frame ``s + lead_frames``
(`EmitterSchedule`).  The emitter pulses follow the left camera strobe (CAM_B).

NOT verified on hardware here (no device on the build machine): the emitter command latency
(``lead_frames``), the exact pulse/exposure alignment, and frame rates above 60 fps.  Verified
without a device: construction, the ImgFrame -> Frame conversion, stack numbering and the emitter
schedule, through a host-side pipeline (``dai.Pipeline(createImplicitDevice=False)`` with a
``dai.node.ThreadedHostNode`` sending ``dai.ImgFrame`` objects) - see tests/test_sensors_oak.py.

Dot profiles (``oak-d-pro``): stacks use the "slots" layout (one dot frame in the L chips of the
source code).  This backend streams the left mono camera only; `edge.runtime.dots.DotsPipeline`
block-matches a mono frame against the nominal projector pattern and a side-by-side ``(H, 2W)``
left | right frame against the de-spread right image.  Pairing CAM_B and CAM_C frames into such
stereo frames is NOT implemented yet, so real-device dot depth is not available; run the profile
without hardware with ``edge run --profile oak-d-pro --sensor sim`` (`edge.sensors.dots`).
"""

from __future__ import annotations

import datetime
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .base import EndOfStream, Frame, SensorInfo, parse_projector_frame

_US = datetime.timedelta(microseconds=1)


def timedelta_ns(td: datetime.timedelta) -> int:
    """A depthai timestamp (datetime.timedelta, microsecond resolution) in integer ns."""
    return (td // _US) * 1000


def frame_from_imgframe(msg: Any, *, projector_frame: int, stack: int, clock_offset_ns: int = 0) -> Frame:
    """Convert one `dai.ImgFrame` (GRAY8/RAW8 -> uint8, RAW16/RAW10.. unpacked -> uint16) to a `Frame`.

    clock_offset_ns: added to the frame's steady-clock timestamp to put it on the host wall clock.
    """
    image = np.array(msg.getFrame(), copy=True)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim != 2:
        raise ValueError(f"OAK frames must be single-channel mono images, got shape {image.shape}")
    if image.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"OAK frames must be uint8 or uint16, got {image.dtype}")
    return Frame(
        image=image,
        sequence=int(msg.getSequenceNum()),
        timestamp_ns=timedelta_ns(msg.getTimestamp()) + int(clock_offset_ns),
        exposure_us=msg.getExposureTime() / _US,
        projector_frame=int(projector_frame),
        stack=int(stack),
    )


@dataclass
class StackNumbering:
    """Sequence number -> (stack id, projector frame id) for a fixed, repeating schedule.

    The first frame seen starts stack 0 at schedule position 0 (``seq0``).
    """

    schedule: np.ndarray
    seq0: int | None = None

    def assign(self, sequence: int) -> tuple[int, int]:
        if self.seq0 is None:
            self.seq0 = int(sequence)
        k = int(sequence) - self.seq0
        stack, pos = divmod(k, len(self.schedule))
        return stack, int(self.schedule[pos])


@dataclass
class EmitterSchedule:
    """Emitter intensities for every schedule position (dot projector, flood light), 0..1.

    A slot whose source-code chip is 1 and whose projector frame is not BLACK turns the dot
    projector on at ``dot_intensity``; everything else turns it off.  ``flood_intensity`` lights the
    flood LED on the WHITE calibration frames (0 = never).
    """

    schedule: np.ndarray
    source_code: str = "1"
    dot_intensity: float = 0.8
    flood_intensity: float = 0.0
    lead_frames: int = 2

    def __post_init__(self) -> None:
        if not self.source_code or set(self.source_code) - {"0", "1"}:
            raise ValueError(f"source code must be a non-empty bit string, got {self.source_code!r}")
        for name in ("dot_intensity", "flood_intensity"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be in 0..1, got {v}")

    def intensities(self, position: int) -> tuple[float, float]:
        """(dot, flood) for schedule position ``position`` (wraps around)."""
        pf = parse_projector_frame(int(self.schedule[position % len(self.schedule)]))
        chip = self.source_code[pf.slot % len(self.source_code)] == "1"
        dot = self.dot_intensity if chip and not pf.is_black else 0.0
        flood = self.flood_intensity if chip and pf.is_white else 0.0
        return dot, flood


@dataclass
class RecordingEmitter:
    """Emitter control without a device: remembers the commands (tests, dry runs)."""

    commands: list[tuple[str, float]] = field(default_factory=list)

    def setIrLaserDotProjectorIntensity(self, intensity: float, mask: int = -1) -> bool:  # noqa: N802 (depthai name)
        self.commands.append(("dot", float(intensity)))
        return True

    def setIrFloodLightIntensity(self, intensity: float, mask: int = -1) -> bool:  # noqa: N802
        self.commands.append(("flood", float(intensity)))
        return True


def camera_output(pipeline: Any, width: int, height: int, fps: float) -> Any:
    """The real camera: CAM_B (left mono) node's GRAY8 output of ``width`` x ``height`` at ``fps``."""
    import depthai as dai

    cam = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_B)
    return cam.requestOutput((int(width), int(height)), dai.ImgFrame.Type.GRAY8, fps=float(fps))


class OakSensor:
    """OAK-D Pro backend (see module docstring).  Constructing it touches no device.

    profile: an `edge.profiles.Profile` (camera size/rate, code, source code).
    pipeline: a depthai pipeline to use (default: ``dai.Pipeline()`` with the implicit device,
        created in `start`); output_factory(pipeline) -> node output (default `camera_output`);
    emitter: object with the two depthai emitter setters (default: the pipeline's device).
    """

    def __init__(self, profile, *, pipeline: Any = None,
                 output_factory: Callable[[Any], Any] | None = None,
                 emitter: Any = None, dot_intensity: float = 0.8, flood_intensity: float = 0.0,
                 lead_frames: int = 2, max_frames: int | None = None) -> None:
        from edge.runtime.pipeline import profile_layout, stack_layout

        n, L = stack_layout(profile)
        layout = profile_layout(profile)  # dots profiles: one dot frame in the L source-code slots
        cam = profile.camera
        self.profile = profile
        self.info = SensorInfo(
            name="oak", width=cam.width, height=cam.height, bits=8, fps=cam.rate_hz,
            n_code_frames=n, source_length=L, metadata={"camera": "CAM_B", "device": "OAK-D Pro"}, layout=layout)
        self._schedule = self.info.schedule
        self.numbering = StackNumbering(self._schedule)
        self.emitters = EmitterSchedule(self._schedule, profile.code.source or "1", dot_intensity,
                                        flood_intensity, lead_frames)
        self._pipeline = pipeline
        self._output_factory = output_factory or (lambda p: camera_output(p, cam.width, cam.height, cam.rate_hz))
        self._emitter = emitter
        self._queue = None
        self._clock_offset_ns = 0
        self._max_frames = max_frames
        self._frames = 0
        self._lock = threading.Lock()

    def start(self) -> None:
        import depthai as dai

        if self._pipeline is None:
            self._pipeline = dai.Pipeline()
        output = self._output_factory(self._pipeline)
        self._queue = output.createOutputQueue(maxSize=64, blocking=False)
        self._clock_offset_ns = time.time_ns() - time.monotonic_ns()
        self._pipeline.start()
        if self._emitter is None:
            self._emitter = self._pipeline.getDefaultDevice()
        self._set_emitters(0)

    def _set_emitters(self, position: int) -> None:
        dot, flood = self.emitters.intensities(position)
        self._emitter.setIrLaserDotProjectorIntensity(dot)
        self._emitter.setIrFloodLightIntensity(flood)

    def read(self, timeout_s: float = 1.0) -> Frame | None:
        if self._queue is None:
            raise ValueError("OakSensor.read called before start()")
        if self._max_frames is not None and self._frames >= self._max_frames:
            raise EndOfStream()
        msg = self._queue.get(datetime.timedelta(seconds=timeout_s)) if timeout_s > 0 else self._queue.tryGet()
        if msg is None:
            if not self._pipeline.isRunning() and not self._queue.has():
                raise EndOfStream()
            return None
        stack, projector_frame = self.numbering.assign(msg.getSequenceNum())
        frame = frame_from_imgframe(msg, projector_frame=projector_frame, stack=stack,
                                    clock_offset_ns=self._clock_offset_ns)
        position = frame.sequence - (self.numbering.seq0 or 0)
        self._set_emitters(position + self.emitters.lead_frames)
        self._frames += 1
        return frame

    def stop(self) -> None:
        with self._lock:
            if self._pipeline is not None and self._queue is not None:
                try:
                    if self._emitter is not None:
                        self._emitter.setIrLaserDotProjectorIntensity(0.0)
                        self._emitter.setIrFloodLightIntensity(0.0)
                finally:
                    if self._pipeline.isRunning():
                        self._pipeline.stop()
                    self._pipeline.wait()
                    self._queue = None

"""What every sensor backend produces: `Frame` records, projector frame ids and the `Sensor` protocol.

A depth map is computed from one *stack* of frames: the ``n`` code frames of the profile's code,
then a white (projector all on) and a black (projector all off) calibration frame.  When the
profile has a light-source code of length ``L``, every one of those ``n + 2`` projector frames is
shown as ``L`` consecutive *slots* (the source code's on/off chips), so a stack holds
``(n + 2) * L`` camera frames.  EDC rounds re-capture *masked* versions of the same frames.

Projector frame ids (defined in `edge.device`, re-exported here) pack these three facts into one
non-negative int::

    id = (edc_round << 16) | (slot << 8) | base

    base       0..n-1  code frame i;  WHITE (0xFE) calibration all-on;  BLACK (0xFF) all-off
    slot       0..L-1  source-code chip (0 when the profile has no source code)
    edc_round  0 = full pattern, r >= 1 = frames masked by adaptive round r

so ``id == i`` for plain code frame ``i`` and ``WHITE``/``BLACK`` are recognisable in a log.

Stack layouts (`SensorInfo.layout`):

    "stack"   coded column patterns: n code frames, WHITE, BLACK, each in L slots ((n + 2) * L
              frames; `stack_schedule`)
    "slots"   one projector frame (the dot pattern or the curtain scan, base 0) in the L slots of
              the source code (L frames; `slot_schedule`): dot projectors, event sensors and light
              curtains, whose depth comes from one de-spread image per code period

Event sensors deliver `EventSlice` records instead of `Frame` records: the events of one slot
(time slice), with the same sequence / stack / projector_frame bookkeeping, so the assembler and
the service treat both alike.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

# The projector frame-id convention and the stack schedules are device facts (`edge.device`); they
# are re-exported here because every backend speaks them.
from edge.device import (BLACK, LAYOUTS, MAX_CODE_FRAMES, MAX_EDC_ROUND, MAX_SLOTS, WHITE,  # noqa: F401
                         ProjectorFrame, layout_schedule, parse_projector_frame, projector_frame_id, slot_schedule,
                         stack_schedule)


@dataclass(frozen=True, slots=True, eq=False)
class Frame:
    """One camera frame as a backend reports it.

    image: (H, W) uint8 or uint16 camera intensities (0..2**bits-1).
    sequence: camera frame counter (consecutive within a stack; gaps mean lost frames).
    timestamp_ns: capture time in ns (host wall clock for sim/replay-as-recorded, device clock
        mapped to host time for OAK).
    exposure_us: exposure in microseconds.
    projector_frame: projector frame id shown during the exposure (see `projector_frame_id`).
    stack: id of the stack (depth map) the frame belongs to; increases by one per stack.
    """

    image: np.ndarray
    sequence: int
    timestamp_ns: int
    exposure_us: float
    projector_frame: int
    stack: int


@dataclass(frozen=True)
class SensorInfo:
    """What the runtime needs to know about a backend before frames arrive.

    width, height: image size (pixels); bits: bits per sample (8 -> uint8 frames, else uint16);
    fps: camera frame rate (frames/s, 0 = as fast as possible); n_code_frames, source_length:
    the stack layout (see `stack_schedule`); name: backend name; metadata: free-form strings
    recorded with the stream (serial number, firmware...).
    """

    name: str
    width: int
    height: int
    bits: int
    fps: float
    n_code_frames: int
    source_length: int = 1
    metadata: dict[str, str] = field(default_factory=dict)
    layout: str = "stack"

    @property
    def schedule(self) -> np.ndarray:
        return layout_schedule(self.layout, self.n_code_frames, self.source_length)

    @property
    def frames_per_stack(self) -> int:
        return int(self.schedule.size)


@dataclass(frozen=True, slots=True, eq=False)
class EventSlice:
    """The events of one time slice (one source-code slot) as an event backend reports them.

    events: (N,) `edge.source.events.EVENT_DTYPE` (x, y u16 pixels; t int64 sensor microseconds;
        p int8 +1 / -1), in arrival order (normally sorted by t; a broken sensor may not be).
    sequence, stack, projector_frame: as for `Frame` (the slot is the id's slot field).
    timestamp_ns: host time the slice was delivered (ns).  exposure_us: slice duration (us).
    t_start_us, t_end_us: the slice's time window [t_start_us, t_end_us) on the sensor clock.
    """

    events: np.ndarray
    sequence: int
    timestamp_ns: int
    exposure_us: float
    projector_frame: int
    stack: int
    t_start_us: int
    t_end_us: int

    @property
    def nbytes(self) -> int:
        return int(self.events.nbytes)


class EndOfStream(Exception):
    """Raised by `Sensor.read` when a finite source (replay, ``--stacks N``) has no more frames."""


@runtime_checkable
class Sensor(Protocol):
    """A frame source.  ``start()``; then ``read()`` from ONE thread; ``stop()`` from any thread."""

    info: SensorInfo

    def start(self) -> None: ...

    def read(self, timeout_s: float = 1.0) -> Frame | None:
        """The next frame, or None when none arrived within ``timeout_s``; EndOfStream at the end."""
        ...

    def stop(self) -> None: ...


@runtime_checkable
class MaskedCapture(Protocol):
    """Backends that can re-capture masked frames for the adaptive EDC loop of one stack."""

    def capture_masked(self, stack: int, edc_round: int, projector_rows: np.ndarray) -> list[Frame]:
        """Capture masked projector frames for ``stack``.

        projector_rows: (m, W_projector) uint8 projector column intensities (0/1 or levels) of
        the m frames to show (every row of a frame is the same: column patterns).
        Returns m frames whose ids carry ``edc_round``.
        """
        ...

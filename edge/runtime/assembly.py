"""Frame assembly: group camera frames into complete stacks, drop and count incomplete ones.

A stack is accepted only when every projector frame of the schedule arrived, in schedule order,
with consecutive sequence numbers and the same stack id.  Anything else (a lost frame, a frame
arriving late, a frame of another stack mixed in) makes the whole stack *incomplete*: it is
dropped, counted, and never reaches the decoder.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..capture import CodedCapture, split_stack
from ..sensors.base import Frame


@dataclass(frozen=True, eq=False)
class Stack:
    """A complete stack of frames for one depth map.

    frames: the frames in schedule order (len == len(schedule)).
    stack: stack id; first_sequence: sequence number of frame 0.
    received_ns: host wall-clock time (time.time_ns) when the last frame arrived.
    """

    stack: int
    frames: tuple[Frame, ...]
    received_ns: int

    @property
    def first_sequence(self) -> int:
        return self.frames[0].sequence

    @property
    def timestamp_ns(self) -> int:
        """Sensor timestamp of the last frame of the stack (ns)."""
        return self.frames[-1].timestamp_ns

    def images(self) -> np.ndarray:
        """(m, H, W) array of the frames' images, schedule order."""
        return np.stack([f.image for f in self.frames])

    def coded(self, images: np.ndarray, n: int, **fields) -> CodedCapture:
        """The `edge.capture.CodedCapture` of this stack's (n + 2, H, W) ``images`` (code frames,
        white, black: the frames' images, or their de-spread form when every image is made of
        several frames, ``len(frames) = (n + 2) * L``).  frame_exposure: microseconds of each
        image (the sum of its frames' ``exposure_us``).  ``fields``: other CodedCapture fields
        (code, columns, stripe, bit_depth, noise)."""
        m = n + 2
        exposure = None
        if len(self.frames) % m == 0:
            per = np.array([f.exposure_us for f in self.frames], dtype=np.float64).reshape(m, -1)
            exposure = per.sum(axis=1)
        return split_stack(images, n, frame_exposure=exposure, exposure_unit="us", **fields)


@dataclass
class AssemblyCounters:
    """Counters of `StackAssembler` (all monotonically increasing)."""

    frames_in: int = 0
    stacks_complete: int = 0
    stacks_incomplete: int = 0
    stacks_cut_at_stop: int = 0
    sequence_gaps: int = 0
    out_of_order: int = 0
    unexpected_frames: int = 0

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass
class StackAssembler:
    """Feed frames one by one with `push`; it returns a `Stack` when one completes.

    schedule: (m,) projector frame ids of a stack in capture order (`stack_schedule`).
    on_frame: optional hook ``on_frame(index, frame)`` (the pipeline's, e.g. the CUDA backend's
    per-frame uploads): called inside `push`, on the pushing thread, for every frame accepted
    into the stack being assembled, with its position ``index`` (0..m-1, schedule order).  A
    stack is assembled from position 0 on; a `Stack` that `push` returns holds exactly the
    Frame objects passed for positions 0..m-1 since the last ``index == 0`` call (of its stack
    id).  A dropped stack just gets no more calls.  The hook must not raise (an exception would
    end the capture); None (the default): no call at all.
    """

    schedule: np.ndarray
    counters: AssemblyCounters = field(default_factory=AssemblyCounters)
    on_frame: Callable[[int, Frame], None] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.schedule = np.asarray(self.schedule, dtype=np.int64).reshape(-1)
        if self.schedule.size == 0:
            raise ValueError("stack schedule must hold at least one projector frame id, got none")
        self._frames: list[Frame] = []
        self._stack: int | None = None
        self._broken = False
        self._last_sequence: int | None = None

    def _drop_current(self) -> None:
        if self._stack is not None and (self._frames or self._broken):
            self.counters.stacks_incomplete += 1
        self._frames = []
        self._stack = None
        self._broken = False

    def push(self, frame: Frame, received_ns: int | None = None) -> Stack | None:
        """Add one frame; returns the completed Stack or None."""
        c = self.counters
        c.frames_in += 1
        last = self._last_sequence
        if last is not None and frame.sequence <= last:
            # Late / duplicated frame: it cannot belong to a stack we still accept.
            c.out_of_order += 1
            if self._stack == frame.stack:
                self._broken = True
            return None
        gap = last is not None and frame.sequence != last + 1
        self._last_sequence = frame.sequence
        if gap:
            c.sequence_gaps += 1

        if frame.stack != self._stack:
            self._drop_current()
            self._stack = frame.stack
        elif gap:
            self._broken = True

        if self._broken:
            return None
        position = len(self._frames)
        if position >= self.schedule.size or frame.projector_frame != self.schedule[position]:
            c.unexpected_frames += 1
            self._broken = True
            self._frames = []
            return None
        self._frames.append(frame)
        if self.on_frame is not None:
            self.on_frame(position, frame)
        if len(self._frames) < self.schedule.size:
            return None
        stack = Stack(frame.stack, tuple(self._frames), time.time_ns() if received_ns is None else received_ns)
        self._frames = []
        self._stack = None
        c.stacks_complete += 1
        return stack

    def flush(self, *, stopping: bool = False) -> None:
        """End of stream: a partly assembled stack is dropped and counted.

        With ``stopping=True`` (the service was asked to stop) a stack that was simply still being
        captured is counted in ``stacks_cut_at_stop`` instead of ``stacks_incomplete``; a stack that
        was already broken (gap, late or unexpected frame) still counts as incomplete.
        """
        if stopping and self._stack is not None and self._frames and not self._broken:
            self.counters.stacks_cut_at_stop += 1
            self._frames = []
            self._stack = None
            return
        self._drop_current()


def check_frame_size(frames, camera) -> None:
    """ValueError unless every image frame of a stack is ``camera.width`` x ``camera.height``
    pixels (the profile's camera: depth maps and published intrinsics have its size).  Frames
    without an image (event slices) are not checked."""
    for i, f in enumerate(frames):
        image = getattr(f, "image", None)
        if image is not None and np.shape(image)[:2] != (camera.height, camera.width):
            raise ValueError(f"stack frame {i}: expected the profile camera's {camera.width}x{camera.height} "
                             f"pixels, got {np.shape(image)[1]}x{np.shape(image)[0]}")

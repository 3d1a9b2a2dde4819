"""Pinned host buffers and streams between a capture and the GPU decoder.

A structured-light stack arrives one frame at a time.  A `StagingSet` is one buffer set: a
page-locked (pinned) host slot per frame, their device copy, a CUDA stream and the device
output arrays; `StagingSet.put` copies a frame into its slot and starts its host -> device
copy on the set's stream, so the uploads run while the camera is still exposing the next
frames; `StagingSet.decode` enqueues the decode (`pipeline.decode_device`) on the same stream
(after the uploads: stream order) and downloads only the outputs asked for (`pipeline.finish`).
Slots: 0..n-1 code frames, n white, n + 1 black, n + 2.. inverse frames (the stack order).

Two users:

* `FrameStager` (the service): frames staged as the capture thread delivers them, keyed by
  stack id, several sets with busy flags, taken by the ONE decode thread for the stack it
  decodes; a stack that was not staged completely decodes by whole-stack upload instead.
  See its docstring for the invariants.
* `Staging` (one thread, stacks that arrive as arrays: `decode_staged`, the bench): put / commit /
  decode over a ring of sets::

    st = Staging(n, (h, w), np.uint8)
    for i, image in enumerate(code_frames): st.put(i, image)
    st.put_white(white); st.put_black(black)
    decoded = st.decode(st.commit(), code, settings, columns=..., stripe=...)

`staging_for` keeps one `Staging` per (n, shape, dtype, inverse) for the runtime's whole-stack
uploads.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Sequence

import numpy as np
from numba import cuda

from ....codes import Code
from ...inputs import validate
from ...search import band_args, check_call
from ...settings import DecodeSettings
from .device import DeviceStack
from .pipeline import FIELDS, decode_device, finish

#: Frame dtypes `FrameStager` stages (camera frames; validated stacks keep them as they are).
STAGED_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16))


class StagingSet:
    """One buffer set: pinned host slots (slots, H, W), their device copy, a stream, and the
    device output arrays of `pipeline.decode_device` (reused from stack to stack).

    Not thread-safe by itself: its owner (`Staging`, `FrameStager`) makes sure one thread at a
    time writes a slot, and that nothing writes a slot while a decode of the set runs."""

    def __init__(self, slots: int, shape: tuple[int, int], dtype: Any) -> None:
        self.slots, self.shape, self.dtype = int(slots), (int(shape[0]), int(shape[1])), np.dtype(dtype)
        self.host = cuda.pinned_array((self.slots, *self.shape), self.dtype)
        self.dev = cuda.device_array((self.slots, *self.shape), self.dtype)
        self.stream = cuda.stream()
        self.buffers: dict = {}

    def put(self, index: int, image: np.ndarray) -> None:
        """Copy `image` (H, W) into pinned slot `index` and enqueue its upload on the set's stream."""
        if not 0 <= index < self.slots:
            raise ValueError(f"staging: expected a slot 0..{self.slots - 1}, got {index}")
        if image.shape != self.shape or image.dtype != self.dtype:
            raise ValueError(f"staging: expected a {self.shape} {self.dtype} frame, got {image.shape} {image.dtype}")
        np.copyto(self.host[index], image)
        self.dev[index].copy_to_device(self.host[index], stream=self.stream)

    def decode(self, n: int, inverse: bool, code: Code, settings: DecodeSettings, *,
               min_disparity: float | None = None, max_disparity: float | None = None, columns: int | None = None,
               stripe: int = 1, bit_depth: int | None = None, outputs: Sequence[str] = FIELDS):
        """Decode the stack held in the slots (n code frames, white, black, n inverse frames when
        `inverse`) on the set's stream; `edge.decode.Decoded` on the host with the fields in
        `outputs` (the others None), the same values as `edge.decode.decode` with these
        arguments.  Returns after the stream finished (nothing of the set is in flight then)."""
        host, dev, stream = self.host, self.dev, self.stream
        inv_host = host[n + 2:n + 2 + n] if inverse else None
        ncols = check_call(code, settings, inverse=inv_host, columns=columns, stripe=stripe)
        stack = validate(host[:n], host[n], host[n + 1], code, inverse=inv_host, bit_depth=bit_depth)
        band = band_args(min_disparity, max_disparity)
        inv_dev = dev[n + 2:n + 2 + n] if inverse else dev[:1, :1, :1]
        ds = DeviceStack(frames=dev[:n], inverse=inv_dev, has_inv=inverse, white=dev[n], black=dev[n + 1],
                         scale=float(stack.scale), dtype=self.dtype, host_white=host[n], host_black=host[n + 1])
        t0 = time.perf_counter()
        out = decode_device(ds, code, settings, columns=ncols, band=band, stripe=stripe, stream=stream,
                            buffers=self.buffers)
        return finish(out, settings, stream, t0=t0, stripe=stripe, outputs=outputs, stack=stack, code=code)


class Staging:
    """A ring of `StagingSet`s for stacks of one shape, filled with put / commit, decoded with
    `decode` (for one thread; `decode_stack` may be called from several).

    n: code frames; shape: (H, W); dtype: the frames' dtype (uint8, uint16, float32, float64);
    inverse: the stacks carry n inverse frames too; sets: buffer sets (2: double buffering)."""

    def __init__(self, n: int, shape: tuple[int, int], dtype: Any, *, inverse: bool = False, sets: int = 2) -> None:
        if n < 1 or len(shape) != 2 or min(shape) < 1:
            raise ValueError(f"Staging: expected n >= 1 and an (H, W) shape, got n={n}, shape={shape}")
        self.n, self.shape, self.dtype, self.inverse = int(n), (int(shape[0]), int(shape[1])), np.dtype(dtype), bool(inverse)
        slots = self.n * (2 if inverse else 1) + 2
        self.slots = slots
        self._sets = [StagingSet(slots, self.shape, self.dtype) for _ in range(sets)]
        self._filled = [np.zeros(slots, bool) for _ in range(sets)]
        self._fill = 0
        self._lock = threading.Lock()
        self._whole = threading.Lock()  # one decode_stack at a time: put .. decode on one set

    def put(self, index: int, image: np.ndarray) -> None:
        """Copy one frame into slot `index` of the set being filled and start its upload (async)."""
        image = np.asarray(image)
        with self._lock:
            k = self._fill
            self._sets[k].put(index, image)
            self._filled[k][index] = True

    def put_white(self, image: np.ndarray) -> None:
        self.put(self.n, image)

    def put_black(self, image: np.ndarray) -> None:
        self.put(self.n + 1, image)

    def commit(self) -> int:
        """Close the set being filled (every slot must have been put); returns its token for
        `decode`; the next frames go to the next set of the ring."""
        with self._lock:
            k = self._fill
            if not self._filled[k].all():
                missing = np.flatnonzero(~self._filled[k]).tolist()
                raise ValueError(f"Staging.commit: slots {missing[:8]} of the stack were never put")
            self._filled[k][:] = False
            self._fill = (k + 1) % len(self._sets)
            return k

    def decode(self, token: int, code: Code, settings: DecodeSettings, **facts: Any):
        """Decode the committed set `token` on its stream (`StagingSet.decode`: facts are
        min_disparity, max_disparity, columns, stripe, bit_depth, outputs)."""
        return self._sets[token].decode(self.n, self.inverse, code, settings, **facts)

    def decode_stack(self, frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code,
                     settings: DecodeSettings, *, inverse: np.ndarray | None = None, **facts: Any):
        """put every frame of a complete stack, commit and decode (a stack that arrives whole).
        Serialised per `Staging` (two threads never interleave their puts in one set)."""
        with self._whole:
            for i in range(self.n):
                self.put(i, frames[i])
            self.put_white(white)
            self.put_black(black)
            if self.inverse:
                for i in range(self.n):
                    self.put(self.n + 2 + i, inverse[i])
            return self.decode(self.commit(), code, settings, **facts)


class FrameStager:
    """Frames staged on the GPU as the capture delivers them, keyed by stack id (the service).

    ``put(index, frame)`` is the capture hook (`edge.runtime.assembly.StackAssembler.on_frame`:
    the frame at position `index` of the stack being assembled, schedule order, slot = index);
    ``decode_frames(frames, ...)`` (the decode thread) decodes a complete stack from the set that
    holds exactly its frames, or returns None so the caller uploads the stack whole.

    slots: frames per stack (n + 2: code frames, white, black; no inverse frames); sets: buffer
    sets (3: one decoding, one complete stack waiting in the queue, one filling).  The sets are
    allocated by `prepare` (the service, before capture starts: `DepthPipeline.prepare_capture`,
    the sensor's shape and dtype) or else for the first frame's shape and dtype (uint8 / uint16); a stack starting with frames of another
    shape / dtype re-allocates them when no set is busy, else it is not staged.

    Invariants (one capture thread calls `put`, one decode thread `decode_frames`; `_lock`
    guards the set states):

    * A set is *free*, *filling* (the capture's current stack), *complete* (every slot put for
      one stack) or *busy* (taken by the decode thread).  `put` writes only into the filling
      set; it never touches a busy set.  Position 0 claims a set: a free one, else the complete
      set finished longest ago (its stack is stale: the service's drop-oldest queue holds the
      newest stacks; its stack, if decoded, falls back); no set left -> the stack is not staged.
      A claimed set's stream is synchronised first (no upload of its previous use in flight).
    * A slot is recorded (the `Frame` object) only after its image was copied into the pinned
      slot and its upload enqueued on the set's stream; a later position is staged only when
      the earlier ones of the same stack id were, so a set's slots always hold one stack's
      frames 0..k in order.  A dropped or broken stack (the assembler stops calling, or
      starts a new stack at position 0) just leaves its set to be reclaimed.
    * The decode thread takes a set only when all its slots hold the very `Frame` objects
      (identity, not equality) of the stack it decodes, and marks it busy under the lock; the
      decode's kernels run on the set's stream after the uploads; the set is freed only after
      `finish` synchronised that stream.  Hence a staged decode reads exactly the stack's
      images, as the whole-stack upload would (frame images are not modified after capture).
    * `put` never raises: an error (a CUDA failure) is kept in `error` and turns staging off;
      every later stack then decodes by whole-stack upload, where the error shows.

    counters: frames_staged, frames_skipped, sets_reclaimed (complete, never taken),
    stacks_taken, stacks_not_staged."""

    def __init__(self, slots: int, *, sets: int = 3) -> None:
        if slots < 3 or sets < 1:
            raise ValueError(f"FrameStager: expected slots >= 3 and sets >= 1, got {slots}, {sets}")
        self.slots, self.nsets = int(slots), int(sets)
        self.shape: tuple[int, int] | None = None
        self.dtype: np.dtype | None = None
        self._sets: list[StagingSet] = []
        self._frames: list[list[Any] | None] = [None] * self.nsets  # recorded Frame per slot
        self._stack: list[int | None] = [None] * self.nsets
        self._busy = [False] * self.nsets
        self._done_at = [0] * self.nsets  # completion order (0: not complete)
        self._ticks = 0
        self._filling: int | None = None
        self._lock = threading.Lock()
        self.error = ""
        self.counters = {"frames_staged": 0, "frames_skipped": 0, "sets_reclaimed": 0, "stacks_taken": 0,
                         "stacks_not_staged": 0}

    # -- capture thread -------------------------------------------------------------------
    def put(self, index: int, frame: Any) -> None:
        """Stage `frame` (a `edge.sensors.base.Frame`: image, stack) at position `index` of its
        stack: copy into the pinned slot and start the upload.  Never raises (see the class)."""
        if self.error:
            return
        try:
            with self._lock:
                self._put(int(index), frame)
        except Exception as exc:  # staging is an optimisation: it never fails a frame
            self.error = f"{type(exc).__name__}: {exc}"
            self._filling = None

    def prepare(self, shape: tuple[int, int], dtype: Any) -> bool:
        """Allocate the sets for (H, W) frames of `dtype` now (before capture: not on the capture
        thread's first frame).  Returns False (nothing allocated) for a dtype that is not
        staged or while a set is busy."""
        with self._lock:
            return self._allocate((int(shape[0]), int(shape[1])), np.dtype(dtype))

    def _allocate(self, shape: tuple[int, int], dtype: np.dtype) -> bool:
        """Sets for this shape / dtype (lock held); a different one replaces idle sets (their
        staged stacks are dropped: they decode by whole-stack upload)."""
        if self._sets and shape == self.shape and dtype == self.dtype:
            return True
        if dtype not in STAGED_DTYPES or min(shape) < 1 or any(self._busy):
            return False
        self._sets = []  # released before the new pinned memory is taken
        self._sets = [StagingSet(self.slots, shape, dtype) for _ in range(self.nsets)]
        self.shape, self.dtype = shape, dtype
        self._frames, self._stack = [None] * self.nsets, [None] * self.nsets
        self._done_at, self._filling = [0] * self.nsets, None
        return True

    def _put(self, index: int, frame: Any) -> None:
        image = np.asarray(frame.image)
        if not 0 <= index < self.slots or image.ndim != 2:
            self.counters["frames_skipped"] += 1
            return
        shape = (int(image.shape[0]), int(image.shape[1]))
        other = shape != self.shape or image.dtype != self.dtype
        if other and not (index == 0 and self._allocate(shape, image.dtype)):  # re-allocate at a stack start
            self.counters["frames_skipped"] += 1
            return
        if index == 0:
            k = self._claim()
            if k is None:
                self.counters["frames_skipped"] += 1
                return
            self._frames[k], self._stack[k], self._done_at[k] = [None] * self.slots, frame.stack, 0
            self._filling = k
        else:
            k = self._filling
            if k is None or self._stack[k] != frame.stack or self._frames[k][index - 1] is None:
                self.counters["frames_skipped"] += 1
                return
        self._sets[k].put(index, image)
        self._frames[k][index] = frame
        self.counters["frames_staged"] += 1
        if index == self.slots - 1:
            self._ticks += 1
            self._done_at[k] = self._ticks
            self._filling = None

    def _claim(self) -> int | None:
        """A set for a new stack (lock held): free, else the oldest complete one, else None."""
        self._filling = None  # an unfinished stack of the capture is abandoned
        idle = [k for k in range(self.nsets) if not self._busy[k]]
        free = [k for k in idle if self._done_at[k] == 0]
        if free:
            k = free[0]
        elif idle:
            k = min(idle, key=lambda j: self._done_at[j])
            self.counters["sets_reclaimed"] += 1
        else:
            return None
        self._frames[k], self._stack[k] = None, None
        self._sets[k].stream.synchronize()
        return k

    # -- decode thread --------------------------------------------------------------------
    def take(self, frames: Sequence[Any]) -> int | None:
        """The set holding exactly these `Frame` objects (identity), now busy; None if none."""
        with self._lock:
            if len(frames) != self.slots:
                return None
            for k in range(self.nsets):
                rec = self._frames[k]
                if (not self._busy[k] and self._done_at[k] and rec is not None
                        and all(a is b for a, b in zip(rec, frames))):
                    self._busy[k] = True
                    return k
            return None

    def release(self, k: int) -> None:
        """Set `k` is free again (its stream has finished: `StagingSet.decode` returned or raised
        after synchronising; synchronised here too for the raise)."""
        try:
            self._sets[k].stream.synchronize()
        finally:
            with self._lock:
                self._busy[k] = False
                self._frames[k], self._stack[k], self._done_at[k] = None, None, 0

    def decode_frames(self, frames: Sequence[Any], code: Code, settings: DecodeSettings, **facts: Any):
        """`edge.decode.Decoded` of the stack made of `frames` (schedule order) from its staged
        set, or None when it was not staged completely (decode it by whole-stack upload).
        facts: as `StagingSet.decode` (min_disparity, max_disparity, columns, stripe, bit_depth,
        outputs).  Called from the decode thread only."""
        k = self.take(frames)
        if k is None:
            self.counters["stacks_not_staged"] += 1
            return None
        try:
            decoded = self._sets[k].decode(self.slots - 2, False, code, settings, **facts)
        finally:
            self.release(k)
        self.counters["stacks_taken"] += 1
        return decoded


_CACHE: dict[tuple, Staging] = {}
_CACHE_LOCK = threading.Lock()


def staging_for(frames: np.ndarray, white: np.ndarray, black: np.ndarray, inverse: np.ndarray | None = None) -> Staging:
    """The process's `Staging` for stacks shaped like these arrays (made on first use)."""
    frames = np.asarray(frames)
    if frames.ndim != 3:
        raise ValueError(f"frames: expected a (n, H, W) stack, got shape {frames.shape}")
    key = (frames.shape, frames.dtype.str, inverse is not None)
    with _CACHE_LOCK:
        st = _CACHE.get(key)
        if st is None:
            if len(_CACHE) >= 4:
                _CACHE.clear()
            st = _CACHE[key] = Staging(frames.shape[0], frames.shape[1:], frames.dtype, inverse=inverse is not None)
        return st


def decode_staged(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, *,
                  settings: DecodeSettings, inverse: np.ndarray | None = None, **facts: Any):
    """`edge.decode.decode` (settings given) through the process's `Staging` for this shape:
    pinned uploads on a stream, the decode on the device, one download of the fields in
    ``outputs`` (a fact; default all).  Same results."""
    stage = staging_for(frames, white, black, inverse)
    return stage.decode_stack(frames, white, black, code, settings, inverse=inverse, **facts)

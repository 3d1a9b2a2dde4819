"""`Staging`: pinned host buffers and streams between a capture and the GPU decoder.

A structured-light stack arrives one frame at a time.  `Staging.put` copies each frame into
its page-locked (pinned) host slot and starts its host -> device copy on the stream of the
buffer set being filled, so the uploads run while the camera is still exposing the next
frames; `Staging.decode` waits only for that stream, decodes on the device
(`pipeline.decode_device`) and copies the results back once.  Two buffer sets (double
buffering): the next stack fills one set while the other is decoded, from one decode thread.

    st = Staging(n, (h, w), np.uint8)
    for i, image in enumerate(code_frames): st.put(i, image)
    st.put_white(white); st.put_black(black)
    decoded = st.decode(st.commit(), code, settings, columns=..., stripe=...)

`staging_for` keeps one `Staging` per (n, shape, dtype, inverse) for the runtime's decode thread.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np
from numba import cuda

from ....codes import Code
from ...inputs import validate
from ...search import band_args, check_call
from ...settings import DecodeSettings
from .device import DeviceStack
from .pipeline import decode_device, finish


class Staging:
    """Pinned host slots + device buffers + a stream per buffer set, for stacks of one shape.

    n: code frames; shape: (H, W); dtype: the frames' dtype (uint8, uint16, float32, float64);
    inverse: the stacks carry n inverse frames too; sets: buffer sets (2: double buffering).
    Slots: 0..n-1 code frames, n white, n + 1 black, n + 2.. inverse frames."""

    def __init__(self, n: int, shape: tuple[int, int], dtype: Any, *, inverse: bool = False, sets: int = 2) -> None:
        if n < 1 or len(shape) != 2 or min(shape) < 1:
            raise ValueError(f"Staging: expected n >= 1 and an (H, W) shape, got n={n}, shape={shape}")
        self.n, self.shape, self.dtype, self.inverse = int(n), (int(shape[0]), int(shape[1])), np.dtype(dtype), bool(inverse)
        slots = self.n * (2 if inverse else 1) + 2
        self.slots = slots
        self._host = [cuda.pinned_array((slots, *self.shape), self.dtype) for _ in range(sets)]
        self._dev = [cuda.device_array((slots, *self.shape), self.dtype) for _ in range(sets)]
        self._streams = [cuda.stream() for _ in range(sets)]
        self._filled = [np.zeros(slots, bool) for _ in range(sets)]
        self._buffers: list[dict] = [{} for _ in range(sets)]  # device outputs, reused per set
        self._fill = 0
        self._lock = threading.Lock()

    def put(self, index: int, image: np.ndarray) -> None:
        """Copy one frame into slot `index` of the set being filled and start its upload (async)."""
        image = np.asarray(image)
        if not 0 <= index < self.slots:
            raise ValueError(f"Staging.put: expected a slot 0..{self.slots - 1}, got {index}")
        if image.shape != self.shape or image.dtype != self.dtype:
            raise ValueError(f"Staging.put: expected a {self.shape} {self.dtype} frame, got {image.shape} {image.dtype}")
        with self._lock:
            k = self._fill
            np.copyto(self._host[k][index], image)
            self._dev[k][index].copy_to_device(self._host[k][index], stream=self._streams[k])
            self._filled[k][index] = True

    def put_white(self, image: np.ndarray) -> None:
        self.put(self.n, image)

    def put_black(self, image: np.ndarray) -> None:
        self.put(self.n + 1, image)

    def commit(self) -> int:
        """Close the set being filled (every slot must have been put); returns its token for
        `decode`; the next frames go to the other set."""
        with self._lock:
            k = self._fill
            if not self._filled[k].all():
                missing = np.flatnonzero(~self._filled[k]).tolist()
                raise ValueError(f"Staging.commit: slots {missing[:8]} of the stack were never put")
            self._filled[k][:] = False
            self._fill = (k + 1) % len(self._host)
            return k

    def decode(self, token: int, code: Code, settings: DecodeSettings, *, min_disparity: float | None = None,
               max_disparity: float | None = None, columns: int | None = None, stripe: int = 1,
               bit_depth: int | None = None):
        """Decode the committed set `token` on its stream; `edge.decode.Decoded` on the host
        (the same results as `edge.decode.decode` with these arguments)."""
        host, dev, stream = self._host[token], self._dev[token], self._streams[token]
        n = self.n
        inverse = host[n + 2:] if self.inverse else None
        ncols = check_call(code, settings, inverse=inverse, columns=columns, stripe=stripe)
        stack = validate(host[:n], host[n], host[n + 1], code, inverse=inverse, bit_depth=bit_depth)
        band = band_args(min_disparity, max_disparity)
        inv_dev = dev[n + 2:] if self.inverse else dev[:1, :1, :1]
        ds = DeviceStack(frames=dev[:n], inverse=inv_dev, has_inv=self.inverse, white=dev[n], black=dev[n + 1],
                         scale=float(stack.scale), dtype=self.dtype, host_white=host[n], host_black=host[n + 1])
        t0 = time.perf_counter()
        out = decode_device(ds, code, settings, columns=ncols, band=band, stripe=stripe, stream=stream,
                            buffers=self._buffers[token])
        return finish(out, settings, stream, t0=t0, stripe=stripe)

    def decode_stack(self, frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code,
                     settings: DecodeSettings, *, inverse: np.ndarray | None = None, **facts: Any):
        """put every frame of a complete stack, commit and decode (a stack that arrives whole)."""
        for i in range(self.n):
            self.put(i, frames[i])
        self.put_white(white)
        self.put_black(black)
        if self.inverse:
            for i in range(self.n):
                self.put(self.n + 2 + i, inverse[i])
        return self.decode(self.commit(), code, settings, **facts)


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
    pinned uploads on a stream, the decode on the device, one download.  Same results."""
    stage = staging_for(frames, white, black, inverse)
    return stage.decode_stack(frames, white, black, code, settings, inverse=inverse, **facts)

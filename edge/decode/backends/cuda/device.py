"""Device-side decoder inputs and the search launches (host wrappers of the kernels).

`DeviceStack` is a validated `edge.decode.inputs.CodedCapture` on the GPU (frames stay in their dtype:
uint8 frames move 1 byte per sample).  `search_device` / `hard_device` launch the kernels on a
`DeviceStack` and return device arrays; `edge.decode.backends.cuda.search` / ``hard`` wrap them
with one upload and one download for the backend seam.  Code tables are uploaded once per code.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import cuda

from ....codes import Code
from ... import kernels
from ....capture import CodedCapture
from ...tables import code_tables
from .. import Q_SCALE
from . import hard as hard_k
from . import nary as nary_k
from . import soft as soft_k
from .cost import LOG_NONE, LOG_PIXEL, LOG_TABLE, MAX_N, pixel_logs

#: A band of at most this many candidate columns per pixel is scanned directly
#: (`soft.band_kernel`); wider bands use the all-codeword kernel restricted to the band.
BAND_SCAN_MAX = 512


@dataclass
class DeviceStack:
    """A `CodedCapture` on the device.  frames (n, H, W), inverse (n, H, W) or a (1, 1, 1) dummy,
    white / black (H, W): device arrays of the frames' dtype; scale: raw -> normalised;
    host_white / host_black: the host copies (the exact per-pixel logs are computed there)."""

    frames: Any
    inverse: Any
    has_inv: bool
    white: Any
    black: Any
    scale: float
    dtype: np.dtype
    host_white: np.ndarray | None = None
    host_black: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.frames.shape[1]), int(self.frames.shape[2])

    def host_levels(self) -> tuple[np.ndarray, np.ndarray]:
        """(white, black) on the host (copied back once where the stack was made on the device)."""
        if self.host_white is None:
            self.host_white = self.white.copy_to_host()
            self.host_black = self.black.copy_to_host()
        return self.host_white, self.host_black


def upload(stack: CodedCapture, stream: Any = 0) -> DeviceStack:
    """Copy a validated `CodedCapture` to the device (on `stream`)."""
    inv = stack.inverse if stack.inverse is not None else stack.frames[:1, :1, :1].copy()
    return DeviceStack(
        frames=cuda.to_device(stack.frames, stream=stream), inverse=cuda.to_device(inv, stream=stream),
        has_inv=stack.inverse is not None, white=cuda.to_device(stack.white, stream=stream),
        black=cuda.to_device(stack.black, stream=stream), scale=float(stack.scale),
        dtype=stack.frames.dtype, host_white=stack.white, host_black=stack.black)


_TABLES: dict[tuple, dict] = {}
_LOGTABS: dict[tuple, Any] = {}
_DUMMY: dict[str, Any] = {}


def device_tables(code: Code) -> dict:
    """The code's tables on the device (uploaded once per code): masks (size,) int64, the
    syndrome tables of `kernels.hard_lean`, the codebook (size, n) uint8, the refit tables."""
    key = (code.name, code.n, code.q, code.size)
    t = _TABLES.get(key)
    if t is None:
        from .refit import refit_tables

        tb = code_tables(code)
        xt, sx, sxx = refit_tables(code)
        t = {"codebook": cuda.to_device(np.ascontiguousarray(code.codebook, np.uint8)),
             "xtab": cuda.to_device(xt), "sx": cuda.to_device(sx), "sxx": cuda.to_device(sxx)}
        if code.q == 2:
            t["masks"] = cuda.to_device(np.ascontiguousarray(tb.masks).view(np.int64))
            t["syndrome"] = bool(tb.linear and tb.has_leader)
            if t["syndrome"]:
                for name in ("syn_col", "info_bit", "leader_info", "leader_wt", "col_of_info"):
                    t[name] = cuda.to_device(np.ascontiguousarray(getattr(tb, name)))
        _TABLES[key] = t
    return t


def _dummy(name: str, shape: tuple, dtype) -> Any:
    a = _DUMMY.get(name)
    if a is None:
        a = _DUMMY[name] = cuda.to_device(np.zeros(shape, dtype))
    return a


def log_inputs(ds: DeviceStack, metric: int, sr2: float, ss2: float, stream: Any = 0) -> tuple[int, Any, Any]:
    """(lmode, ltab, plog) of the cost model: the CPU's logs of the white / black variances
    (ML without inverse frames only): a `kernels.log_levels` table for integer frames, per-pixel
    logs (`cost.pixel_logs`, computed on the host) for float frames."""
    ltab = _dummy("ltab", (1,), np.float64)
    plog = _dummy("plog", (2, 1, 1), np.float64)
    if metric != kernels.METRIC_ML or ds.has_inv:
        return LOG_NONE, ltab, plog
    if ds.dtype in (np.uint8, np.uint16):
        levels = 256 if ds.dtype == np.uint8 else 65536
        key = (levels, ds.scale, sr2, ss2)
        tab = _LOGTABS.get(key)
        if tab is None:
            if len(_LOGTABS) > 16:
                _LOGTABS.clear()
            tab = _LOGTABS[key] = cuda.to_device(kernels.log_levels(levels, ds.scale, sr2, ss2))
        return LOG_TABLE, tab, plog
    logs = pixel_logs(*ds.host_levels(), ds.scale, sr2, ss2)
    return LOG_PIXEL, ltab, cuda.to_device(logs, stream=stream)


def buffer(buffers: dict | None, name: str, shape: tuple, dtype: Any, stream: Any = 0) -> Any:
    """A device array: buffers[name] when it has this shape and dtype (reused across stacks:
    no allocation per frame), else a new one (kept in `buffers` when given)."""
    a = None if buffers is None else buffers.get(name)
    if a is None or tuple(a.shape) != tuple(shape) or a.dtype != np.dtype(dtype):
        a = cuda.device_array(shape, dtype, stream=stream)
        if buffers is not None:
            buffers[name] = a
    return a


def _outputs(h: int, w: int, stream: Any, buffers: dict | None = None, prefix: str = "") -> tuple[Any, Any, Any]:
    return (buffer(buffers, prefix + "candidates", (h, w, 3), np.int32, stream),
            buffer(buffers, prefix + "distances", (h, w, 3), np.float32, stream),
            buffer(buffers, prefix + "confidence", (h, w), np.float32, stream))


def _blocks(pixels: int, tpb: int) -> int:
    return max(1, (pixels + tpb - 1) // tpb)


def search_device(ds: DeviceStack, code: Code, *, metric: int, sigma_r: float, sigma_s: float,
                  columns: int, band: tuple[bool, int, int], stripe: int, path: str | None = None,
                  stream: Any = 0, buffers: dict | None = None, prefix: str = "") -> tuple[Any, Any, Any, dict]:
    """Exact soft top-3 on the device: (candidates, distances, confidence) device arrays + stats.

    path (binary codes): "all" (every codeword, restricted to the band if one is given) or
    "band" (a scan of each pixel's band); default "band" for a band of at most
    `BAND_SCAN_MAX` columns, else "all".  Both return the CPU backend's arrays exactly.
    stats: path, seconds (host time of the launches; kernels run asynchronously, callers that
    copy the results back replace it with the whole time).  buffers / prefix: output arrays
    reused from a caller's dict (`buffer`)."""
    h, w = ds.shape
    n = int(ds.frames.shape[0])
    use_band, min_d, max_d = band
    sr2, ss2 = float(sigma_r) ** 2, float(sigma_s) ** 2
    q_scale = float(Q_SCALE[metric])
    tb = device_tables(code)
    cand, dist, conf = _outputs(h, w, stream, buffers, prefix)
    t0 = time.perf_counter()
    if code.q != 2:
        if n * code.q > nary_k.MAX_NQ:
            raise ValueError(f"backend 'cuda': n * q = {n * code.q} exceeds {nary_k.MAX_NQ} for code {code.name!r}")
        logs = _dummy("nlogs", (code.q, 1, 1), np.float64)
        if metric == kernels.METRIC_ML:
            logs = cuda.to_device(nary_k.nary_logs(*ds.host_levels(), ds.has_inv, ds.scale,
                                                   code.q, sr2, ss2), stream=stream)
        nary_k.soft_nary[_blocks(h * w, nary_k.TPB), nary_k.TPB, stream](
            ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, ds.scale, metric, sr2, ss2, q_scale,
            code.q, logs, tb["codebook"], columns, use_band, min_d, max_d, stripe, cand, dist, conf)
        return cand, dist, conf, {"path": "cuda-nary", "seconds": time.perf_counter() - t0}
    if n > MAX_N:
        raise ValueError(f"backend 'cuda': binary codes need n <= {MAX_N}, got {n} for {code.name!r}")
    if path is None:
        path = "band" if use_band and (max_d - min_d) // stripe + 2 <= BAND_SCAN_MAX else "all"
    if path == "band" and not use_band:
        raise ValueError("path: 'band' needs min_disparity / max_disparity")
    lmode, ltab, plog = log_inputs(ds, metric, sr2, ss2, stream)
    ngroups = (n + 3) // 4
    if path == "band":
        kern, tpb = soft_k.band_kernel(ngroups)
        kern[_blocks(h * w, tpb), tpb, stream](
            ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, ds.scale, metric, sr2, ss2, q_scale,
            lmode, ltab, plog, tb["masks"], columns, min_d, max_d, stripe, cand, dist, conf)
    elif path == "all":
        kern, tpb = soft_k.full_kernel(ngroups)
        kern[_blocks(h * w, tpb), tpb, stream](
            ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, ds.scale, metric, sr2, ss2, q_scale,
            lmode, ltab, plog, tb["masks"], columns, use_band, min_d, max_d, stripe, cand, dist, conf)
    else:
        raise ValueError(f"path: expected 'all' or 'band', got {path!r}")
    return cand, dist, conf, {"path": f"cuda-{path}", "seconds": time.perf_counter() - t0}


def hard_device(ds: DeviceStack, code: Code, *, columns: int, band: tuple[bool, int, int], stripe: int,
                stream: Any = 0, buffers: dict | None = None, prefix: str = "") -> tuple[Any, Any, Any, dict]:
    """Hard decisions + nearest codeword on the device (see `edge.decode.backends` ``hard``)."""
    tb = device_tables(code)
    if code.q == 2 and tb["syndrome"]:
        h, w = ds.shape
        cand, dist, conf = _outputs(h, w, stream, buffers, prefix)
        use_band, min_d, max_d = band
        t0 = time.perf_counter()
        hard_k.hard_syndrome[_blocks(h * w, hard_k.TPB), hard_k.TPB, stream](
            ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, tb["syn_col"], tb["info_bit"],
            tb["leader_info"], tb["leader_wt"], tb["col_of_info"], int(code.d_min), columns, use_band,
            min_d, max_d, stripe, cand, dist, conf)
        return cand, dist, conf, {"path": "cuda-syndrome", "seconds": time.perf_counter() - t0}
    cand, dist, conf, st = search_device(ds, code, metric=kernels.METRIC_HARD, sigma_r=1.0, sigma_s=0.0,
                                         columns=columns, band=band, stripe=stripe, stream=stream,
                                         buffers=buffers, prefix=prefix)
    st["path"] = "cuda-hamming-search"
    return cand, dist, conf, st

"""Whole decodes on the device: levels (calibration or refit), search, valid mask.

`decode_device` runs on a `DeviceStack` and leaves its results on the device; `decode_whole` is
`edge.decode.decode` for backend "cuda" (the decoder hands the whole call over): the same
argument checks, one upload, and one download of the outputs (`finish`: only the `Decoded`
fields asked for, each array once through `to_host`; the runtime asks for `HOST_OUTPUTS`).
Methods "soft" / "hard" get their valid mask on the device (`validity`); "list" / "median" /
"list+median" take the device's candidates, confidence and eligibility to the host filters of
`edge.decode.spatial` (sequential along rows, as the CPU backend does).  ``levels="refit"`` follows
`edge.decode.decode_refined` (one refit iteration) with `refit`'s kernels.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ....codes import Code
from ...inputs import validate
from ...search import METRICS, band_args, check_call
from ...settings import DecodeSettings
from . import refit as refit_k
from . import validity as valid_k
from .device import DeviceStack, _blocks, _dummy, buffer, device_tables, hard_device, search_device, upload


def _search(ds: DeviceStack, code: Code, method: str, s: DecodeSettings, metric: int, columns: int,
            band: tuple[bool, int, int], stripe: int, stream: Any, buffers: dict | None, prefix: str = ""):
    if method == "hard":
        return hard_device(ds, code, columns=columns, band=band, stripe=stripe, stream=stream, buffers=buffers,
                           prefix=prefix)
    return search_device(ds, code, metric=metric, sigma_r=s.sigma_r, sigma_s=s.sigma_s, columns=columns,
                         band=band, stripe=stripe, stream=stream, buffers=buffers, prefix=prefix)


def refit_stack(ds: DeviceStack, code: Code, s: DecodeSettings, metric: int, *, columns: int,
                band: tuple[bool, int, int], stripe: int, stream: Any = 0, buffers: dict | None = None) -> DeviceStack:
    """`edge.decode.decode_refined`'s levels on the device: normalise, `initial_levels`, one decode
    ("hard" for method "hard", else "soft"), `refine_levels`.  Returns the float32 stack with
    the refitted levels (scale 1) that the final decode uses."""
    if ds.has_inv:
        raise ValueError("levels: 'refit' expects no inverse frames (pattern + inverse decisions "
                         "do not use the calibration levels), got inverse=")
    n = int(ds.frames.shape[0])
    h, w = ds.shape
    f = buffer(buffers, "refit_frames", (n, h, w), np.float32, stream)
    wv = buffer(buffers, "refit_white0", (h, w), np.float32, stream)
    bv = buffer(buffers, "refit_black0", (h, w), np.float32, stream)
    grid = _blocks(h * w, refit_k.TPB)
    refit_k.normalise[grid, refit_k.TPB, stream](ds.frames, ds.white, ds.black, np.float32(ds.scale), f, wv, bv)
    refit_k.initial_levels[grid, refit_k.TPB, stream](f, wv, bv)
    dummy = _dummy("inv32", (1, 1, 1), np.float32)
    first = DeviceStack(frames=f, inverse=dummy, has_inv=False, white=wv, black=bv, scale=1.0,
                        dtype=np.dtype(np.float32))
    cand, _, _, _ = _search(first, code, "hard" if s.method == "hard" else "soft", s, metric, columns, band,
                            stripe, stream, buffers, prefix="refit_")
    tb = device_tables(code)
    w2 = buffer(buffers, "refit_white", (h, w), np.float32, stream)
    b2 = buffer(buffers, "refit_black", (h, w), np.float32, stream)
    refit_k.refine_levels[grid, refit_k.TPB, stream](f, wv, bv, tb["xtab"], tb["sx"], tb["sxx"], cand, w2, b2)
    return DeviceStack(frames=f, inverse=dummy, has_inv=False, white=w2, black=b2, scale=1.0,
                       dtype=np.dtype(np.float32))


def decode_device(ds: DeviceStack, code: Code, s: DecodeSettings, *, columns: int, band: tuple[bool, int, int],
                  stripe: int, stream: Any = 0, buffers: dict | None = None) -> dict[str, Any]:
    """Levels, search and (methods "soft" / "hard") the valid mask on the device.

    Returns device arrays: candidates (H, W, 3) int32, distances (H, W, 3) float32, confidence
    (H, W) float32, column0 (H, W) int32 (best candidate), eligible (H, W) bool, and for "soft" /
    "hard" column (H, W) int32 (-1 where invalid) and valid (H, W) bool; plus stats.
    buffers: a dict that keeps the device arrays between calls (no allocation per stack)."""
    metric = METRICS[s.metric]
    if s.levels == "refit":
        ds = refit_stack(ds, code, s, metric, columns=columns, band=band, stripe=stripe, stream=stream,
                         buffers=buffers)
    cand, dist, conf, st = _search(ds, code, s.method, s, metric, columns, band, stripe, stream, buffers)
    h, w = ds.shape
    grid = _blocks(h * w, valid_k.TPB)
    col0 = buffer(buffers, "column0", (h, w), np.int32, stream)
    elig = buffer(buffers, "eligible", (h, w), np.bool_, stream)
    valid_k.eligible_column[grid, valid_k.TPB, stream](cand, ds.white, ds.black, np.float32(ds.scale),
                                                       np.float32(s.min_contrast), col0, elig)
    from ...decoder import band_choices  # N of method "sgm" (host stage)

    out = {"candidates": cand, "distances": dist, "confidence": conf, "column0": col0, "eligible": elig,
           "stats": st, "choices": band_choices(columns, band, stripe)}
    if s.method in ("soft", "hard"):
        column = buffer(buffers, "column", (h, w), np.int32, stream)
        valid = buffer(buffers, "valid", (h, w), np.bool_, stream)
        valid_k.support_mask[grid, valid_k.TPB, stream](
            col0, conf, elig, bool(s.spatial_check), float(s.t_high), 3, 1, np.float32(s.min_confidence),
            np.float32(s.t_low), column, valid)
        out["column"], out["valid"] = column, valid
    return out


#: The `edge.decode.Decoded` array fields, in order (what `finish` can download).
FIELDS = ("column", "confidence", "valid", "candidates", "distances")
#: The fields the service's depth uses (`edge.runtime.pipeline.DepthPipeline`: column, confidence
#: and the valid mask); the runtime's GPU path downloads only these.
HOST_OUTPUTS = ("column", "confidence", "valid")


def to_host(name: str, array: Any, stream: Any = 0) -> np.ndarray:
    """One device -> host copy of the output `name` (on `stream`, asynchronous on a real stream).

    Every result `finish` brings back goes through here, one call per array (a seam: tests
    count the arrays and bytes copied back)."""
    return array.copy_to_host(stream=stream)


def _outputs(outputs) -> frozenset[str]:
    want = frozenset(outputs)
    unknown = sorted(want - set(FIELDS))
    if unknown:
        raise ValueError(f"outputs: expected names among {', '.join(FIELDS)}, got {unknown}")
    return want


def finish(out: dict[str, Any], s: DecodeSettings, stream: Any = 0, t0: float | None = None, *, stripe: int = 1,
           outputs=FIELDS):
    """Device results of `decode_device` -> `edge.decode.Decoded`, downloading only what is needed.

    outputs: the `Decoded` fields wanted on the host (default all of `FIELDS`; the runtime asks
    for `HOST_OUTPUTS`).  Fields not in `outputs` are None in the returned `Decoded`.  What is
    copied back (each array once, through `to_host`): methods "soft" / "hard" download exactly
    the wanted fields (column, valid come from the device's mask); "list" / "median" /
    "list+median" download candidates, confidence, column0 and eligible (the host stages
    `spatial_stage` + `valid_mask` need them) and distances only when wanted ("sgm": always).  The values of
    the fields returned do not depend on `outputs`.  stats gains ``downloaded`` (the names
    copied back) and ``download_bytes``.  t0: perf_counter at the upload; stats["seconds"]
    becomes the time from it to the results on the host.  stripe: projector columns per
    codebook row (the spatial filters work in projector pixels)."""
    from ...decoder import Decoded
    from ...spatial import spatial_stage
    from ...validity import valid_mask

    want = _outputs(outputs)
    if s.method in ("soft", "hard"):
        names = [f for f in FIELDS if f in want]
    else:
        names = ["candidates", "confidence", "column0", "eligible"] + (
            ["distances"] if "distances" in want or s.method == "sgm" else [])
    host = {k: to_host(k, out[k], stream) for k in names}
    if stream != 0:
        stream.synchronize()
    st = out["stats"]
    if t0 is not None:
        st["seconds"] = time.perf_counter() - t0
    st["downloaded"] = list(names)
    st["download_bytes"] = int(sum(a.nbytes for a in host.values()))
    if s.method in ("soft", "hard"):
        column, valid = host.get("column"), host.get("valid")
    else:
        spatial = spatial_stage(s, host["candidates"], host["confidence"], host["column0"], host["eligible"],
                                stripe=stripe, distances=host.get("distances"), choices=out.get("choices"))
        column, valid = valid_mask(spatial, host["confidence"], host["eligible"], s)
    got = {"column": column, "valid": valid, "confidence": host.get("confidence"),
           "candidates": host.get("candidates"), "distances": host.get("distances")}
    return Decoded(**{f: (got[f] if f in want else None) for f in FIELDS}, stats=st)


def decode_whole(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, settings: DecodeSettings, *,
                 inverse: np.ndarray | None = None, min_disparity: float | None = None,
                 max_disparity: float | None = None, columns: int | None = None, stripe: int = 1,
                 bit_depth: int | None = None, outputs=FIELDS):
    """`edge.decode.decode` on the device (same arguments, same `Decoded`, same results).

    outputs: the `Decoded` fields to download (`finish`; default all: the library's full
    `Decoded`); the others are None."""
    ncols = check_call(code, settings, inverse=inverse, columns=columns, stripe=stripe)
    band = band_args(min_disparity, max_disparity)
    stack = validate(frames, white, black, code, inverse=inverse, bit_depth=bit_depth)
    t0 = time.perf_counter()
    out = decode_device(upload(stack), code, settings, columns=ncols, band=band, stripe=stripe)
    return finish(out, settings, t0=t0, stripe=stripe, outputs=outputs)

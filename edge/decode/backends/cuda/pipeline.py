"""Whole decodes on the device: levels (calibration or refit), search, valid mask.

`decode_device` runs on a `DeviceStack` and leaves its results on the device; `decode_whole` is
`edge.decode.decode` for backend "cuda" (the decoder hands the whole call over): the same
argument checks, one upload, and one download of the outputs (`finish`: only the `Decoded`
fields asked for, each array once through `to_host`; the runtime asks for `HOST_OUTPUTS`).
Methods "soft" / "hard" get their valid mask on the device (`validity`); "list" / "median" /
"list+median" take the device's candidates, confidence and eligibility to the host filters of
`edge.decode.spatial` (sequential along rows, as the CPU backend does).  ``levels="refit"`` follows
`edge.decode.decode_refined` (one refit iteration) with `refit`'s kernels.  Under the "error"
validity rule (`DecodeSettings.rule`) `decode_device` hands over to `error_device`
(`edge.decode.decoder._decode_error_rule` with `posterior`'s kernels); `finish` then also
downloads ``error`` (the `Decoded` field).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numba import cuda

from ....capture import CodedCapture
from ....codes import Code
from ... import kernels
from ...inputs import validate
from ...posterior import MIN_FIT_PIXELS, normalised32
from ...search import METRICS, band_args, check_call
from ...settings import DecodeSettings
from . import posterior as post_k
from . import refit as refit_k
from . import validity as valid_k
from .cost import SIM
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
    buffers: a dict that keeps the device arrays between calls (no allocation per stack).
    Under the "error" validity rule (``s.rule(...) == "error"``): `error_device`'s dict instead."""
    metric = METRICS[s.metric]
    if s.rule(ds.has_inv) == "error":
        return error_device(ds, code, s, metric, columns=columns, band=band, stripe=stripe, stream=stream,
                            buffers=buffers)
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
           "stats": st, "choices": band_choices(columns, band, stripe), "rows": columns}
    if s.levels == "refit":  # the goodness-of-fit test (`finish`) reads the levels the search used
        out["refit_white"], out["refit_black"] = ds.white, ds.black
    if s.method in ("soft", "hard"):
        column = buffer(buffers, "column", (h, w), np.int32, stream)
        valid = buffer(buffers, "valid", (h, w), np.bool_, stream)
        valid_k.support_mask[grid, valid_k.TPB, stream](
            col0, conf, elig, bool(s.spatial_check), float(s.t_high), 3, 1, np.float32(s.min_confidence),
            np.float32(s.t_low), column, valid)
        out["column"], out["valid"] = column, valid
    return out


_POST_TABLES: dict[tuple, dict] = {}


def posterior_tables(code: Code, inverse: bool) -> dict:
    """The error rule's code tables on the device (uploaded once per code and inverse flag):
    xtab (`posterior._xtab`, float64 symbols / (q - 1), with inverse frames their 1 - x too) and
    the tail-mass tables of `posterior._flips` (packed, flips, flip_bits, flip_w on the device;
    weight, wlo, whi, nflips on the host)."""
    from ...posterior import _flips, _xtab

    key = (code.name, code.n, code.q, code.size, bool(inverse))
    t = _POST_TABLES.get(key)
    if t is None:
        tail = _flips(code)
        t = {"xtab": cuda.to_device(_xtab(code, inverse)), "packed": cuda.to_device(tail.packed),
             "flips": cuda.to_device(tail.flips), "flip_bits": cuda.to_device(np.ascontiguousarray(tail.flip_bits)),
             "flip_w": cuda.to_device(tail.flip_w), "weight": float(tail.weight), "wlo": int(tail.wlo),
             "whi": int(tail.whi), "nflips": int(tail.flips.shape[0])}
        _POST_TABLES[key] = t
    return t


class StageClock:
    """Where the error rule's time goes on the device: a CUDA event recorded on the decode's
    stream at each stage boundary (`mark`), read after the results are on the host (`stage_ms`).

    An event completes when the stream reaches it, so a stage's milliseconds are the device
    time between two boundaries, including the host steps in between (the noise fit, the
    not-lit lookup: the stream idles while the host works, then the next launch follows) and
    the downloads they wait for.  Invariant: the marks are in stream order and `stage_ms` is read
    only after the stream finished (`finish` synchronises first).  Under the simulator events
    carry no time: `stage_ms` is None."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream
        self.marks: list[tuple[str, Any]] = []
        self.mark("start")

    def mark(self, name: str) -> None:
        """Record the boundary after stage `name` on the stream (asynchronous)."""
        if not SIM:
            ev = cuda.event()
            ev.record(self.stream)
            self.marks.append((name, ev))

    def stage_ms(self) -> dict[str, float] | None:
        """{stage: milliseconds} in stream order; None under the simulator."""
        if len(self.marks) < 2:  # under the simulator `mark` records nothing
            return None
        self.marks[-1][1].synchronize()
        return {name: round(float(prev.elapsed_time(ev)), 4)
                for (_, prev), (name, ev) in zip(self.marks, self.marks[1:])}


def _fetch(name: str, array: Any, stream: Any, log: list) -> np.ndarray:
    """A download the host stages of the error rule need now (`to_host`, then the stream)."""
    out = to_host(name, array, stream)
    if stream != 0:
        stream.synchronize()
    log.append((name, int(out.nbytes)))
    return out


def error_device(ds: DeviceStack, code: Code, s: DecodeSettings, metric: int, *, columns: int,
                 band: tuple[bool, int, int], stripe: int, stream: Any = 0,
                 buffers: dict | None = None) -> dict[str, Any]:
    """`edge.decode.decoder._decode_error_rule` with the frames on the device (`posterior`'s kernels).

    Levels (`DecodeSettings.level_source`): "split" (``levels="auto"``, binary codes) splits each
    pixel's samples on the device (`posterior.split_levels` + `normalise`: the float32 stack the
    search reads); "refit" is `refit_stack`; otherwise the calibration levels.  Then the search,
    the subgrid fit stats (the host fits the noise model and the level prior
    from them: `edge.decode.posterior._noise_from`, `edge.decode.level_prior.level_prior`), the posterior kernel, the gain histogram
    (atomics; the host turns its counts into the not-lit lookup, `posterior.fdr_lookup`), the
    tail mass where it is due and P(not lit) < 1/2 (`tail_kernel`) and error / valid.  Host <-> device traffic besides the results: the split's compact fit stats
    (at most `FIT_PIXELS` pixels), the on / off levels where the ML search needs the CPU's
    per-pixel logs (no inverse frames), the subgrid fit stats, nb + 2 histogram counters down
    and the (nb + 1,) lookup up.  Returns device arrays candidates / distances (the posterior's:
    re-ordered by likelihood, negative log-likelihoods), confidence, error, column0, misfit (the
    goodness-of-fit statistic of the best candidates, `posterior.Posterior.misfit`), column /
    valid (methods "soft" / "hard"; the others get them on the host in `finish`), ``rule``
    "error", stats (the search's + noise_a, noise_beta, noise_fitted, rule, levels, level_source,
    and ``side_downloads``: (name, bytes) of the intermediate downloads), and ``clock``, the
    stages' `StageClock` (`finish` puts its ``stage_ms`` in the stats: levels, search, fit_stats,
    noise_fit, posterior, not_lit_lookup, tail, download, and the host's publish_host)."""
    from ...decoder import band_choices
    from ...level_prior import kernel_args, level_prior
    from ...posterior import (GAIN_BIN, SKIP_MARGIN, SPLIT_ITERATIONS, TAIL_FLOOR, _noise_from, _steps, fdr_lookup,
                              fit_size, fit_step, gain_bins, lit_noise)

    h, w = ds.shape
    n = int(ds.frames.shape[0])
    ns = 2 * n if ds.has_inv else n
    grid = _blocks(h * w, post_k.TPB)
    scale32 = np.float32(ds.scale)
    scale = np.float64(scale32)  # the CPU's error rule works with float(float32(scale))
    like = np.empty((ns, 1, 1), ds.dtype)  # `_noise_from` reads the samples' dtype and count only
    side: list = []
    clock = StageClock(stream)
    s_in = s
    source = s.level_source("error", code.q)
    if source == "refit":
        searched = refit_stack(ds, code, s, metric, columns=columns, band=band, stripe=stripe, stream=stream,
                               buffers=buffers)
    elif source == "split":
        step, k = fit_step(h * w), fit_size(h * w)
        on = buffer(buffers, "split_on", (h, w), np.float32, stream)
        off = buffer(buffers, "split_off", (h, w), np.float32, stream)
        s2 = buffer(buffers, "split_s2", (k,), np.float64, stream)
        mu = buffer(buffers, "split_mu", (k,), np.float64, stream)
        post_k.split_levels[grid, post_k.TPB, stream](ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, scale,
                                                      int(SPLIT_ITERATIONS), step, on, off, s2, mu)
        f32 = buffer(buffers, "split_frames", (n, h, w), np.float32, stream)
        inv32 = (buffer(buffers, "split_inverse", (n, h, w), np.float32, stream) if ds.has_inv
                 else _dummy("inv32", (1, 1, 1), np.float32))
        post_k.normalise[grid, post_k.TPB, stream](ds.frames, ds.inverse, ds.has_inv, scale32, f32, inv32)
        first = _noise_from(_fetch("split_s2", s2, stream, side), _fetch("split_mu", mu, stream, side), like,
                            float(scale), (s.sigma_r, s.sigma_s))
        host_on = host_off = None
        if s.method != "hard" and metric == kernels.METRIC_ML and not ds.has_inv:  # the CPU's per-pixel logs
            host_on, host_off = _fetch("split_on", on, stream, side), _fetch("split_off", off, stream, side)
        searched = DeviceStack(frames=f32, inverse=inv32, has_inv=ds.has_inv, white=on, black=off, scale=1.0,
                               dtype=np.dtype(np.float32), host_white=host_on, host_black=host_off)
        s = s.with_noise(first.a, first.beta)
    else:
        searched = ds
    clock.mark("levels")
    cand, dist, _, st = _search(searched, code, s.method, s, metric, columns, band, stripe, stream, buffers)
    clock.mark("search")
    tb = posterior_tables(code, ds.has_inv)
    sy, sx = _steps(h, w)
    rows, cols = -(-h // sy), -(-w // sx)
    fs2 = buffer(buffers, "fit_s2", (rows, cols), np.float64, stream)
    fmu = buffer(buffers, "fit_mu", (rows, cols), np.float64, stream)
    fb = buffer(buffers, "fit_b", (rows, cols), np.float64, stream)
    fc = buffer(buffers, "fit_c", (rows, cols), np.float64, stream)
    post_k.fit_stats[_blocks(rows * cols, post_k.TPB), post_k.TPB, stream](
        ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, scale, tb["xtab"], cand, sy, sx, fs2, fmu, fb, fc)
    clock.mark("fit_stats")
    host_b, host_c = _fetch("fit_b", fb, stream, side), _fetch("fit_c", fc, stream, side)
    noise = lit_noise(_fetch("fit_s2", fs2, stream, side), _fetch("fit_mu", fmu, stream, side), host_b, host_c, like,
                      float(scale), (s.sigma_r, s.sigma_s), code, ds.has_inv)
    noise = noise._replace(levels=level_prior(host_b, host_c))
    clock.mark("noise_fit")  # downloads and host fits: the stream idles until the host gets here
    ptab, pu0, pdu, pw0, pdw, pout, use_prior, pmin = kernel_args(noise.levels)
    choices = band_choices(columns, band, stripe)
    pc = buffer(buffers, "post_candidates", (h, w, 3), np.int32, stream)
    pd = buffer(buffers, "post_distances", (h, w, 3), np.float32, stream)
    pconf = buffer(buffers, "post_confidence", (h, w), np.float32, stream)
    comp = buffer(buffers, "post_competitors", (h, w), np.float64, stream)
    gain = buffer(buffers, "post_gain", (h, w), np.float64, stream)
    due = buffer(buffers, "post_tail_due", (h, w), np.uint8, stream)
    far = buffer(buffers, "post_far", (h, w), np.float64, stream)
    every = buffer(buffers, "post_every", (h, w), np.float64, stream)
    lbest = buffer(buffers, "post_lbest", (h, w), np.float64, stream)
    misfit = buffer(buffers, "misfit", (h, w), np.float32, stream)
    d_ptab = cuda.to_device(ptab, stream=stream)
    nflips = tb["nflips"]
    post_k.posterior_kernel[grid, post_k.TPB, stream](
        ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, scale, tb["xtab"], cand, dist,
        float(SKIP_MARGIN), float(noise.a), float(noise.beta), nflips, tb["weight"], float(TAIL_FLOOR),
        d_ptab, pu0, pdu, pw0, pdw, pout, use_prior, pc, pd, comp, gain, pconf, far, every, lbest, due, misfit)
    clock.mark("posterior")
    median, nb = gain_bins(code, choices, ds.has_inv)
    counts = cuda.to_device(np.zeros(nb + 2, np.int64), stream=stream)
    post_k.gain_histogram[grid, post_k.TPB, stream](gain, float(GAIN_BIN), nb, float(median), counts)
    c = _fetch("gain_counts", counts, stream, side)
    total = int(c[nb])
    lookup = (np.zeros(nb + 1) if total == 0
              else fdr_lookup(c[:nb], total, int(c[nb + 1]), code, choices, ds.has_inv))
    d_lookup = cuda.to_device(lookup, stream=stream)
    clock.mark("not_lit_lookup")
    if nflips:
        post_k.tail_kernel[grid, post_k.TPB, stream](
            ds.frames, ds.inverse, ds.has_inv, ds.white, ds.black, scale, tb["xtab"], int(code.n), pc, due, far,
            every, lbest, gain, d_lookup, float(GAIN_BIN), nb, float(noise.a), float(noise.beta), tb["packed"],
            tb["flips"], tb["flip_bits"], tb["flip_w"], tb["weight"], tb["wlo"], tb["whi"],
            min(1.0, choices / code.size), float(TAIL_FLOOR), d_ptab, pu0, pdu, pw0, pdw, pout, use_prior, pmin,
            comp)
    err = buffer(buffers, "error", (h, w), np.float32, stream)
    col0 = buffer(buffers, "column0", (h, w), np.int32, stream)
    column = buffer(buffers, "column", (h, w), np.int32, stream)
    valid = buffer(buffers, "valid", (h, w), np.bool_, stream)
    post_k.error_valid[grid, post_k.TPB, stream](gain, comp, pc, d_lookup,
                                                 float(GAIN_BIN), nb, np.float32(s.max_error), err, col0, column,
                                                 valid)
    clock.mark("tail")  # the tail mass (none where the code has no tail table) and error / valid
    st = dict(st, noise_a=noise.a, noise_beta=noise.beta, noise_fitted=noise.fitted, rule="error",
              levels=s_in.levels, level_source=source, side_downloads=side)
    out = {"rule": "error", "candidates": pc, "distances": pd, "confidence": pconf, "error": err, "column0": col0,
           "misfit": misfit, "stats": st, "choices": choices, "rows": columns, "noise": noise, "clock": clock}
    if s.method in ("soft", "hard"):
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
           outputs=FIELDS, stack: CodedCapture | None = None, code: Code | None = None):
    """Device results of `decode_device` -> `edge.decode.Decoded`, downloading only what is needed.

    outputs: the `Decoded` fields wanted on the host (default all of `FIELDS`; the runtime asks
    for `HOST_OUTPUTS`).  Fields not in `outputs` are None in the returned `Decoded`.  What is
    copied back (each array once, through `to_host`): methods "soft" / "hard" download exactly
    the wanted fields (column, valid come from the device's mask; under the "error" rule
    ``error`` and ``misfit`` (the host's goodness-of-fit test) too, always, and the "list" /
    "median" / "sgm" methods take candidates, confidence, distances and error to the host
    stages); confidence-rule "list" / "median" /
    "list+median" download candidates, confidence, column0 and eligible (the host stages
    `spatial_stage` + `valid_mask` need them) and distances only when wanted ("sgm": always).
    Under the confidence rule every method but "hard" also takes column0 (and with
    ``levels="refit"`` the refitted white / black) to the host for the goodness-of-fit test
    (`_confidence_fit`), on captures of at least `MIN_FIT_PIXELS` pixels.  The values of
    the fields returned do not depend on `outputs`.  stats gains ``downloaded`` (the names
    copied back, the error rule's intermediate downloads first) and ``download_bytes``.  t0:
    perf_counter at the upload; stats["seconds"]
    becomes the time from it to the results on the host.  stripe: projector columns per
    codebook row (the spatial filters work in projector pixels).  stack, code: the host capture
    and its code (method "sgm" under the "error" rule: `edge.decode.decoder.sgm_stage` scores
    the neighbours' columns on the host samples)."""
    from ...decoder import Decoded, untested_fit
    from ...spatial import spatial_stage
    from ...validity import valid_mask

    want = _outputs(outputs)
    rule = out.get("rule", "confidence")
    # the confidence rule's goodness-of-fit test (`decoder.confidence_fit`, host) needs the best
    # candidate where its noise fit can run at all (a capture of >= MIN_FIT_PIXELS pixels)
    tested = rule == "confidence" and s.method != "hard"
    fit = tested and out["column0"].size >= MIN_FIT_PIXELS
    if s.method in ("soft", "hard"):
        names = [f for f in FIELDS if f in want or ((rule == "error" or fit) and f in ("column", "valid"))]
        if fit:
            names.append("column0")
    elif rule == "error":
        names = ["candidates", "confidence", "distances"]  # the methods' published error needs the distances
    else:
        names = ["candidates", "confidence", "column0", "eligible"] + (
            ["distances"] if "distances" in want or s.method == "sgm" else [])
    if rule == "error":
        names += ["error", "misfit"]
    if fit and "refit_white" in out:  # the refitted on / off levels (float32) the search read
        names += ["refit_white", "refit_black"]
    host = {k: to_host(k, out[k], stream) for k in names}
    clock = out.get("clock")
    if clock is not None:
        clock.mark("download")
    if stream != 0:
        stream.synchronize()
    st = out["stats"]
    if clock is not None:
        st["stage_ms"] = clock.stage_ms()
    if t0 is not None:
        st["seconds"] = time.perf_counter() - t0
    side = st.pop("side_downloads", [])
    st["downloaded"] = [k for k, _ in side] + list(names)
    st["download_bytes"] = int(sum(a.nbytes for a in host.values())) + int(sum(b for _, b in side))
    if rule == "error":
        # the goodness-of-fit test and the method, on the host (`decoder.publish_error_rule`, as
        # the CPU backend): soft / hard from the device's published columns
        from ...decoder import publish_error_rule

        if stack is None or code is None:
            raise ValueError("finish: the 'error' rule needs the host stack and its code")
        if s.method in ("soft", "hard"):
            cand = np.full(host["valid"].shape + (3,), -1, np.int32)
            cand[..., 0] = np.where(host["valid"], host["column"], -1)
        else:
            cand = host["candidates"]
        t_pub = time.perf_counter()
        column, valid, cand, dist, err = publish_error_rule(
            stack, code, s, out["noise"], cand, host.get("distances"), host["error"], rows=out["rows"],
            choices=out["choices"], stripe=stripe, misfit=host.pop("misfit"))
        if st.get("stage_ms") is not None:  # host only: the goodness-of-fit test and the method
            st["stage_ms"]["publish_host"] = round(1e3 * (time.perf_counter() - t_pub), 4)
        if s.method not in ("soft", "hard"):
            host.update(candidates=cand, distances=dist)
        host["error"] = err
    elif s.method in ("soft", "hard"):
        column, valid = host.get("column"), host.get("valid")
    else:
        spatial = spatial_stage(s, host["candidates"], host["confidence"], host["column0"], host["eligible"],
                                stripe=stripe, distances=host.get("distances"), choices=out.get("choices"),
                                columns=out.get("rows"))
        column, valid = valid_mask(spatial, host["confidence"], host["eligible"], s)
    if fit:
        column, valid = _confidence_fit(st, s, host, column, stack, code)
    elif tested:  # too few pixels for the noise fit: nothing tested
        st.update(untested_fit())
    got = {"column": column, "valid": valid, "confidence": host.get("confidence"),
           "candidates": host.get("candidates"), "distances": host.get("distances")}
    return Decoded(**{f: (got[f] if f in want else None) for f in FIELDS}, stats=st, error=host.get("error"))


def _confidence_fit(st: dict[str, Any], s: DecodeSettings, host: dict[str, np.ndarray], column: np.ndarray,
                    stack: CodedCapture | None, code: Code | None) -> tuple[np.ndarray, np.ndarray]:
    """The confidence rule's goodness-of-fit test on the host, as the CPU backend runs it
    (`edge.decode.decoder.confidence_fit` on the capture the search read: the host ``stack``, or
    with ``levels="refit"`` its frames as float32 normalised and the device's refitted levels
    ``host["refit_white"]`` / ``host["refit_black"]``), from the device's best candidates
    ``host["column0"]``.  Adds its stats (``misfit_noise`` / ``misfit_threshold`` /
    ``misfit_dropped``) to ``st``."""
    from ...decoder import confidence_fit

    if stack is None or code is None:
        raise ValueError("finish: the 'confidence' rule's goodness-of-fit test needs the host stack and its code")
    searched = stack
    if "refit_white" in host:
        searched = validate(normalised32(stack.frames, stack.scale), host["refit_white"], host["refit_black"], code,
                            scale_free=True)
    column, valid, stats = confidence_fit(searched, code, s, host["column0"], column)
    st.update(stats)
    return column, valid


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
    return finish(out, settings, t0=t0, stripe=stripe, outputs=outputs, stack=stack, code=code)

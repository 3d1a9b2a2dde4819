"""The CUDA backend's exactness checks, run by tests/test_decode_cuda.py in a subprocess.

    python tests/_cuda_checks.py [--full]

Without --full: tiny images (the numba-cuda simulator, ``NUMBA_ENABLE_CUDASIM=1``, runs each
GPU thread in Python); with --full (a real GPU): 600 x 700 / 120 x 160 images.  Prints one
JSON object per line: {"check": name, "ok": bool, "detail": str}.  Every check compares the
CUDA backend's arrays with the CPU backend's (np.array_equal: bit for bit) and, for the soft
searches, with the brute-force reference of tests/test_decode.py.
"""

from __future__ import annotations

import json
import sys
import time
import traceback
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from edge.codes import get_code  # noqa: E402
from edge.decode import decode  # noqa: E402
from edge.decode.backends import Q_SCALE, cpu, resolve  # noqa: E402
from edge.decode.backends import cuda as gpu  # noqa: E402
from edge.decode.inputs import validate  # noqa: E402
from edge.decode.kernels import METRIC_HARD, METRIC_ML, METRIC_NORMALIZED  # noqa: E402
from edge.decode.synthetic import make_capture  # noqa: E402
from test_decode import NOT_A_CANDIDATE, check_exact, reference_costs  # noqa: E402

FULL = "--full" in sys.argv
SR, SS = 0.01, 0.03
FIELDS = ("column", "confidence", "valid", "candidates", "distances")


def yield_while_polled() -> None:
    """Make the simulator's block loop hand the GIL to the threads it waits for.

    Under the simulator every GPU thread is a Python thread, and `BlockManager.run` polls the
    live ones (`is_alive`, non-blocking) in a loop that never sleeps, so it keeps the GIL from the
    few threads still working: a block with one long pixel (a tail mass over hundreds of words)
    ran about 20x slower than its own work.  Here a poll that finds its thread alive sleeps for
    0 s, which releases the GIL to that work.  The kernels and their results are untouched;
    raising the switch interval instead would slow every thread start in a busy block.
    """
    from numba.cuda.simulator import kernel as sim

    polled = sim.BlockThread.is_alive

    def is_alive(thread) -> bool:
        if polled(thread):
            time.sleep(0)
            return True
        return False

    sim.BlockThread.is_alive = is_alive


def emit(name: str, ok: bool, detail: str = "") -> None:
    print(json.dumps({"check": name, "ok": bool(ok), "detail": detail}), flush=True)


def capture(code, h, w, *, dtype=np.uint8, inverse=False, seed=0, band_center=None, dark=0.1):
    """A synthetic capture; columns near x - band_center when given (a disparity band), some
    pixels with white <= black."""
    rng = np.random.default_rng(seed)
    if band_center is None:
        cols = rng.integers(0, code.size, (h, w))
    else:
        x = np.arange(w)[None, :]
        cols = np.clip(x - band_center + rng.integers(-2, 3, (h, w)), 0, code.size - 1)
    cap = make_capture(code, cols, rng=rng, albedo=rng.uniform(0.02, 0.6, (h, w)), sigma_s=0.06,
                       dtype=dtype, inverse=inverse)
    white, black = cap.white.copy(), cap.black.copy()
    off = rng.random((h, w)) < dark
    white[off] = black[off]
    return cap, white, black


def same_candidates(cpu, device) -> bool:
    """Decoded.candidates of the CPU and a device backend agree: equal, except that the CPU's soft
    search under the error rule does not locate a candidate more than `posterior.SKIP_MARGIN`
    behind the best (`edge.decode.kernels.soft_lanes`' margin): there the CPU has -1 and the
    device a row whose distance is inf (not rescored)."""
    if cpu.candidates is None or device.candidates is None:
        return cpu.candidates is device.candidates
    if cpu.candidates.shape != device.candidates.shape:
        return False
    moved = cpu.candidates != device.candidates
    return bool((cpu.candidates[moved] == -1).all() and np.isinf(device.distances[moved]).all())


def same_arrays(a, b) -> tuple[bool, str]:
    bad = [i for i, (x, y) in enumerate(zip(a, b)) if not np.array_equal(x, y)]
    return not bad, f"differs in outputs {bad}" if bad else ""


def check_search(name, code_name, *, h, w, dtype=np.uint8, inverse=False, metric=METRIC_ML, band=(False, 0, 0),
                 columns=None, stripe=1, brute=False, path=None, bit_depth=None):
    code = get_code(code_name)
    cap, white, black = capture(code, h, w, dtype=dtype, inverse=inverse, dark=0.0 if brute else 0.1,
                                band_center=(band[1] + band[2]) // 2 if band[0] else None)
    st = validate(cap.frames, white, black, code, inverse=cap.inverse, bit_depth=bit_depth)
    kw = dict(metric=metric, sigma_r=SR, sigma_s=SS, columns=code.size if columns is None else columns,
              band=band, stripe=stripe)
    ref = cpu.search(st, code, **kw)
    got = gpu.search(st, code, path=path, **kw)
    ok, detail = same_arrays(ref[:3], got[:3])
    detail += f" path {got[3]['path']}"
    if ok and brute:
        from edge.decode import Decoded

        mname = "ml" if metric == METRIC_ML else "normalized"
        arrays = [cap.frames, white, black, cap.inverse]
        if dtype == np.uint16:  # the reference takes uint8 or normalised floats
            arrays = [None if a is None else a.astype(np.float64) * st.scale for a in arrays]
        costs = reference_costs(*arrays[:3], code, inverse=arrays[3], metric=mname)
        if band[0]:  # candidates outside the pixel's band are not candidates
            x = np.arange(w)[:, None]
            c = np.arange(code.size)[None, :]
            inside = (c >= (x - band[2]) // stripe) & (c <= (x - band[1]) // stripe)
            costs = np.where(inside[None], costs, NOT_A_CANDIDATE)
        d = Decoded(column=got[0][..., 0], confidence=got[2], valid=got[0][..., 0] >= 0, candidates=got[0],
                    distances=got[1])
        try:
            check_exact(d, costs, tol=code.n / Q_SCALE[metric])
        except AssertionError as e:
            ok, detail = False, f"brute force: {e}"
    emit(name, ok, detail)


def check_hard(name, code_name, *, h, w, inverse=False, band=(False, 0, 0)):
    code = get_code(code_name)
    cap, white, black = capture(code, h, w, inverse=inverse)
    st = validate(cap.frames, white, black, code, inverse=cap.inverse)
    kw = dict(columns=code.size, band=band, stripe=1)
    ref, got = cpu.hard(st, code, **kw), gpu.hard(st, code, **kw)
    ok, detail = same_arrays(ref[:3], got[:3])
    emit(name, ok, detail + f" path {got[3]['path']} (cpu {ref[3]['path']})")


def check_decode(name, code_name, *, h, w, dtype=np.uint8, inverse=False, **opts):
    code = get_code(code_name)
    cap, white, black = capture(code, h, w, dtype=dtype, inverse=inverse, band_center=4, dark=0.05)
    kw = dict(inverse=cap.inverse, min_disparity=0, max_disparity=8, **opts)
    ref = decode(cap.frames, white, black, code, backend="cpu", **kw)
    got = decode(cap.frames, white, black, code, backend="cuda", **kw)
    ok, detail = same_arrays([getattr(ref, f) for f in FIELDS], [getattr(got, f) for f in FIELDS])
    emit(name, ok and int(ref.valid.sum()) > 0, detail + f" valid {int(ref.valid.sum())} path {got.stats['path']}")


def check_confidence_fit(name, code_name, *, h, w, **opts):
    """The "confidence" rule's goodness-of-fit test (`decoder.confidence_fit`) on the device path
    (`pipeline._confidence_fit`): on a capture with enough pixels for its noise fit the CUDA
    decode gives the CPU's fields bit for bit and the same misfit noise / threshold / dropped
    count; the test ran (noise fitted) and the device's best candidates went to the host."""
    code = get_code(code_name)
    cap, white, black = capture(code, h, w, band_center=4, dark=0.05)
    kw = dict(min_disparity=0, max_disparity=8, validity="confidence", **opts)
    ref = decode(cap.frames, white, black, code, backend="cpu", **kw)
    with Downloads() as dl:
        got = decode(cap.frames, white, black, code, backend="cuda", **kw)
    ok, detail = same_arrays([getattr(ref, f) for f in FIELDS], [getattr(got, f) for f in FIELDS])
    keys = ("misfit_noise", "misfit_threshold", "misfit_dropped")
    same_stats = all(ref.stats.get(k) == got.stats.get(k) for k in keys)
    refit = opts.get("levels") == "refit"
    ok &= same_stats and ref.stats.get("misfit_noise") is not None and "column0" in dl.names
    ok &= ("refit_white" in dl.names) == refit and int(ref.valid.sum()) > 0
    emit(name, ok, detail + f" stats cpu {[ref.stats.get(k) for k in keys]} cuda {[got.stats.get(k) for k in keys]}"
                            f" downloaded {dl.names}")


#: Tolerance of the error rule's float outputs, device vs CPU: relative 1e-6 (distances are
#: negative log-likelihoods, error a probability); exact under the simulator (same float64 ops,
#: the CPU's log / exp), last-bit differences of the device's log / exp on a GPU.
ERR_RTOL, ERR_ATOL = 1e-6, 1e-7
#: the error rule's stages timed on a GPU (`pipeline.StageClock`, `finish`), in order
STAGES = ("levels", "search", "fit_stats", "noise_fit", "posterior", "not_lit_lookup", "tail", "download",
          "publish_host")


def error_agrees(ref, got) -> bool:
    """P(wrong) of the CPU (ref) and the device (got) agree: within ERR_RTOL everywhere (both
    add the tail mass in a second pass, on the same pixels: `posterior._tail_pass`,
    `tail_kernel`)."""
    if ref is None or got is None or ref.shape != got.shape:
        return False
    return bool(np.allclose(ref, got, rtol=ERR_RTOL, atol=ERR_ATOL, equal_nan=True))


def check_error_rule(name, code_name, *, h, w, inverse=False, band=True, dtype=np.uint8, fitted=None, **opts):
    """decode(..., backend="cuda") under the "error" rule (`pipeline.error_device`) against the
    CPU's `_decode_error_rule`: column / valid identical, candidates too (`same_candidates`), error / distances /
    confidence within ERR_RTOL, the same fitted noise model; some pixels valid and some not."""
    code = get_code(code_name)
    cap, white, black = capture(code, h, w, dtype=dtype, inverse=inverse, band_center=4 if band else None,
                                dark=0.1)
    kw = dict(inverse=cap.inverse, validity="error", **opts)
    if band:
        kw.update(min_disparity=0, max_disparity=8)
    ref = decode(cap.frames, white, black, code, backend="cpu", **kw)
    with Downloads() as dl:
        got = decode(cap.frames, white, black, code, backend="cuda", **kw)
    bad = [f for f in ("column", "valid") if not np.array_equal(getattr(ref, f), getattr(got, f))]
    if not same_candidates(ref, got):
        bad.append("candidates")
    if not error_agrees(ref.error, got.error):
        bad.append("error")
    for f in ("distances", "confidence"):
        a, b = getattr(ref, f), getattr(got, f)
        if a is None or b is None or a.shape != b.shape or not np.allclose(a, b, rtol=ERR_RTOL, atol=ERR_ATOL,
                                                                           equal_nan=True):
            bad.append(f)
    noise = [ref.stats.get(k) == got.stats.get(k) for k in ("noise_a", "noise_beta", "noise_fitted")]
    nv = int(ref.valid.sum())
    on_device = got.stats.get("rule") == "error" and "error" in dl.names and "gain_counts" in dl.names
    ok = not bad and all(noise) and 0 < nv < ref.valid.size and on_device
    ok &= got.stats.get("level_source") == ref.stats.get("level_source") is not None  # the same levels stage
    ms = got.stats.get("stage_ms")  # the StageClock: no times under the simulator, every stage on a GPU
    ok &= ms is None if gpu.SIM else (isinstance(ms, dict) and list(ms) == list(STAGES)
                                      and all(v >= 0 for v in ms.values()))
    # fitted: >= MIN_FIT_PIXELS decoded (the binned fit ran); unless stated, the --full sizes (at
    # least 19,200 pixels) always get there and the simulator's tiny images never do
    ok &= bool(got.stats.get("noise_fitted")) == (FULL if fitted is None else fitted)
    derr = float(np.nanmax(np.abs(ref.error - got.error)))
    emit(name, ok, f"differs in {bad}, noise same {noise}, valid {nv}/{ref.valid.size}, max |d error| {derr:.2e}, "
                   f"path {got.stats.get('path')}, downloaded {dl.names}, stage ms {ms}")


def check_posterior_prior(name, code_name, *, h, w, inverse=False, a=3e-4):
    """posterior_kernel with a level prior (decode's error rule has one wherever the noise fit has
    `level_prior.MIN_PIXELS` pixels, more than these tiny captures) against the CPU's
    `posterior._posterior` on the same inputs: candidates equal, distances / competitor mass /
    gain / confidence within ERR_RTOL; some pixels with a tail mass."""
    from numba import cuda

    from edge.decode import posterior as P
    from edge.decode.backends.cuda import posterior as post_k
    from edge.decode.backends.cuda.pipeline import posterior_tables
    from edge.decode.level_prior import contrast_edges, kernel_args, level_prior

    code = get_code(code_name)
    cap, white, black = capture(code, h, w, inverse=inverse, band_center=4, dark=0.1, seed=5)
    rng = np.random.default_rng(7)
    truth = np.clip(np.arange(w)[None, :] - 4, 0, code.size - 1) + np.zeros((h, 1), np.int64)
    cand = np.stack([truth, rng.integers(0, code.size, (h, w)), (truth + 9) % code.size], -1).astype(np.int32)
    searched = np.zeros(cand.shape, np.float32)
    off = rng.uniform(0.0, 0.1, 4000)
    prior = level_prior(off, rng.uniform(0.0, 0.6, 4000))
    beta = 1e-3
    ptab, pu0, pdu, pw0, pdw, pout, use, least = kernel_args(prior)
    edges = contrast_edges(prior)
    tail = P._flips(code)
    packed, flips, weight, wlo, whi = tail.packed, tail.flips, tail.weight, tail.wlo, tail.whi
    scale = 1.0 / 255.0
    samples = P._samples(cap.frames, cap.inverse)
    xtab = P._xtab(code, inverse)
    ref = [np.empty((h, w, 3), np.int32), np.empty((h, w, 3), np.float32), np.empty((h, w)), np.empty((h, w)),
           np.empty((h, w), np.float32), np.empty((h, w), np.float32)]
    due, far, every, lbest = (np.empty((h, w), np.uint8), np.empty((h, w)), np.empty((h, w)), np.empty((h, w)))
    misfit = np.empty((h, w), np.float32)
    P._posterior(samples, white, black, scale, xtab, P._words(code, inverse), cand, searched, a, beta, flips,
                 float(weight), True, 1,
                 ptab, pu0, pdu, pw0, pdw, pout, use, edges, *ref, far, every, lbest, due, misfit)
    # every due pixel's tail (P(not lit) = 0 everywhere, on both)
    P._tail_pass(samples, white, black, scale, xtab, code.n, ref[0], due, far, every, lbest,
                 np.zeros((h, w), np.int64), np.zeros(1), a, beta, packed, flips, tail.columns, float(weight),
                 int(wlo), int(whi), 1.0, 1, ptab, pu0, pdu, pw0, pdw, pout, use, least, edges,
                 P._skip_cost(flips.size * weight), ref[2])
    tb = posterior_tables(code, inverse)
    out = [cuda.device_array((h, w, 3), np.int32), cuda.device_array((h, w, 3), np.float32),
           cuda.device_array((h, w)), cuda.device_array((h, w)), cuda.device_array((h, w), np.float32)]
    d_due, d_far, d_every, d_lbest = (cuda.device_array((h, w), np.uint8), cuda.device_array((h, w)),
                                      cuda.device_array((h, w)), cuda.device_array((h, w)))
    d_misfit = cuda.device_array((h, w), np.float32)
    inv = cuda.to_device(cap.inverse if inverse else np.zeros((1, 1, 1), cap.frames.dtype))
    grid = (h * w + post_k.TPB - 1) // post_k.TPB
    d_frames, d_white, d_black, d_ptab = (cuda.to_device(cap.frames), cuda.to_device(white), cuda.to_device(black),
                                          cuda.to_device(ptab))
    post_k.posterior_kernel[grid, post_k.TPB](
        d_frames, inv, inverse, d_white, d_black, scale, tb["xtab"], cuda.to_device(cand), cuda.to_device(searched),
        float(P.SKIP_MARGIN), a, beta, tb["nflips"], tb["weight"], float(P.TAIL_FLOOR), d_ptab, pu0, pdu, pw0, pdw,
        pout, use, *out, d_far, d_every, d_lbest, d_due, d_misfit)
    def tail_pass(not_lit, out_comp):
        """tail_kernel with P(not lit) = not_lit for every finite gain (one bin)."""
        post_k.tail_kernel[grid, post_k.TPB](
            d_frames, inv, inverse, d_white, d_black, scale, tb["xtab"], int(code.n), out[0], d_due, d_far, d_every,
            d_lbest, out[3], cuda.to_device(np.full(2, not_lit)), 1.0, 1, a, beta, tb["packed"], tb["flips"],
            tb["flip_bits"], tb["flip_w"], tb["weight"], tb["wlo"], tb["whi"], 1.0, float(P.TAIL_FLOOR), d_ptab, pu0,
            pdu, pw0, pdw, pout, use, least, out_comp)

    tail_pass(0.0, out[2])  # every due pixel's tail, as the CPU's above
    got = [o.copy_to_host() for o in out]
    ok_due = np.array_equal(d_due.copy_to_host(), due)
    # and with P(not lit) = 3/4 for every gain the tail is left out, as on the CPU
    shadow = cuda.to_device(np.full((h, w), -1.0))
    tail_pass(0.75, shadow)
    ok_due &= bool((shadow.copy_to_host() == -1.0).all())
    ok = np.array_equal(got[0], ref[0])
    same_misfit = np.array_equal(d_misfit.copy_to_host(), misfit, equal_nan=True) and np.isfinite(misfit).any()
    close = [np.allclose(g, r, rtol=ERR_RTOL, atol=ERR_ATOL, equal_nan=True)
             for g, r in zip(got[1:], [ref[1], ref[2], ref[3], ref[4]])]
    # pixels whose competitor mass (ref[2]) has a tail term: it differs from the top three's alone
    top3 = [np.empty_like(r) for r in ref]
    P._posterior(samples, white, black, scale, xtab, P._words(code, inverse), cand, searched, a, beta,
                 np.zeros(0, np.uint64), 1.0,
                 True, 1, ptab, pu0, pdu, pw0, pdw, pout, use, edges, *top3, np.empty((h, w)), np.empty((h, w)),
                 np.empty((h, w)), np.empty((h, w), np.uint8), np.empty((h, w), np.float32))
    tails = int((ref[2] != top3[2]).sum())
    emit(name, ok and ok_due and all(close) and use and 0 < tails and same_misfit,
         f"candidates equal {ok}, tail due mask and shadow gate as on the CPU {ok_due}, distances / competitors / gain / confidence close {close}, "
         f"misfit equal {same_misfit}, "
         f"prior {use}, pixels with a tail mass {tails}/{h * w}")


def _prior_lookup(ptab, pu0, pdu, pw0, pdw, pout, bs, cs, out):
    """`check_prior_cost`'s kernel (compiled there): one (b, c) pair per thread."""
    i = cuda.grid(1)  # noqa: F821 - a global set by check_prior_cost
    if i < out.size:
        out[i] = post_k._prior_cost(ptab, pu0, pdu, pw0, pdw, pout, bs[i], cs[i])  # noqa: F821


def check_prior_cost(name):
    """The device's level-prior lookup (`backends.cuda.posterior._prior_cost`) against the CPU's
    `level_prior.cost_at` on levels at, inside and off the grid, at C_FLOOR, and not finite
    (b or c = inf, NaN: off the grid on both): equal bit for bit."""
    global cuda, post_k  # the kernel's globals (the simulator swaps a kernel's global `cuda`)
    from numba import cuda

    from edge.decode.backends.cuda import posterior as post_k
    from edge.decode.level_prior import C_FLOOR, cost_at, kernel_args, level_prior

    rng = np.random.default_rng(3)
    prior = level_prior(rng.uniform(0.0, 0.1, 4000), rng.uniform(0.0, 0.6, 4000))
    ptab, pu0, pdu, pw0, pdw, pout, _, _ = kernel_args(prior)
    b = np.concatenate([rng.uniform(-0.05, 0.2, 200), [0.0, 0.05, np.inf, 0.05, np.nan, 0.0, 1e300]])
    c = np.concatenate([10.0 ** rng.uniform(-4.0, 0.5, 200), [C_FLOOR, 0.0, 0.3, np.inf, 0.3, np.nan, 1e-300]])
    ref = np.array([cost_at(ptab, pu0, pdu, pw0, pdw, pout, bi, ci) for bi, ci in zip(b, c)])

    out = cuda.device_array(b.size, np.float64)
    cuda.jit(_prior_lookup)[(b.size + 63) // 64, 64](cuda.to_device(np.ascontiguousarray(ptab)), pu0, pdu, pw0, pdw,
                                                     pout, cuda.to_device(b), cuda.to_device(c), out)
    got = out.copy_to_host()
    outside = int((ref == pout).sum())
    emit(name, np.array_equal(got, ref), f"{b.size} levels, {outside} off the grid")


def check_error_rule_reduced(name):
    """The reduced download under the "error" rule (`pipeline.decode_whole` and `Staging.decode`
    with the runtime's `HOST_OUTPUTS`): column, confidence, valid and error come back with the
    CPU's values (and misfit, the host's goodness-of-fit test's statistic); candidates / distances stay on the device; the other downloads are the small
    noise-fit / histogram arrays only (counted at the `to_host` seam, = stats download_bytes)."""
    from edge.decode.backends.cuda.pipeline import HOST_OUTPUTS, decode_whole
    from edge.decode.backends.cuda.staging import Staging
    from edge.decode.settings import DEFAULT_SETTINGS

    code = get_code("ecc-22-10")
    h, w = 3, 24
    cap, white, black = capture(code, h, w, band_center=4, dark=0.1)
    s = DEFAULT_SETTINGS.replace(validity="error", backend="cuda")
    facts = dict(min_disparity=0, max_disparity=8)
    ref = decode(cap.frames, white, black, code, settings=s.replace(backend="cpu"), **facts)
    details, ok = [], int(ref.valid.sum()) > 0
    small = {"split_s2", "split_mu", "fit_s2", "fit_mu", "fit_b", "fit_c", "gain_counts", "split_on", "split_off"}
    for label in ("whole", "staged"):
        with Downloads() as dl:
            if label == "whole":
                got = decode_whole(cap.frames, white, black, code, s, outputs=HOST_OUTPUTS, **facts)
            else:
                stage = Staging(code.n, (h, w), cap.frames.dtype)
                got = stage.decode_stack(cap.frames, white, black, code, s, outputs=HOST_OUTPUTS, **facts)
        results = [k for k in dl.names if k not in small]
        same = all(np.array_equal(getattr(ref, f), getattr(got, f)) for f in ("column", "valid"))
        close = (np.allclose(ref.confidence, got.confidence, rtol=ERR_RTOL, atol=ERR_ATOL)
                 and error_agrees(ref.error, got.error))
        ok &= same and close and sorted(results) == sorted(["column", "confidence", "valid", "error", "misfit"])
        ok &= set(dl.names) - set(results) <= small and "gain_counts" in dl.names
        ok &= got.candidates is None and got.distances is None and got.stats.get("rule") == "error"
        ok &= dl.bytes == got.stats["download_bytes"]
        details.append(f"{label}: downloaded {dl.names} ({dl.bytes} B), same {same}, close {close}")
    emit(name, ok, "; ".join(details) + f"; valid {int(ref.valid.sum())}")


def check_validity(name, *, h, w):
    """The device valid mask against validity.eligible_column / spatial_support / final_mask on
    crafted columns (clusters, near ties of the median, even voter counts)."""
    from numba import cuda

    from edge.decode.backends.cuda import validity as vk
    from edge.decode.spatial import spatial_support
    from edge.decode.validity import eligible_column, final_mask

    rng = np.random.default_rng(7)
    cand = rng.integers(0, 6, (h, w, 3)).astype(np.int32)
    cand[rng.random((h, w)) < 0.1] = -1
    conf = rng.choice(np.float32([0.0, 0.04, 0.05, 0.2, 0.3, 0.29999998, 0.31, 0.9]), (h, w))
    white = rng.integers(0, 40, (h, w)).astype(np.uint8)
    black = rng.integers(0, 20, (h, w)).astype(np.uint8)
    scale, min_c, min_conf, t_low, t_high = np.float32(1 / 255), np.float32(0.02), np.float32(0.3), np.float32(0.05), 0.3
    col0, elig = np.empty((h, w), np.int32), np.empty((h, w), bool)
    eligible_column(cand, white, black, scale, min_c, col0, elig)
    ok = True
    for use in (True, False):
        support = spatial_support(col0, conf, elig, t_vote=t_high) if use else elig
        col, valid = np.empty((h, w), np.int32), np.empty((h, w), bool)
        final_mask(col0, conf, elig, support, use, min_conf, t_low, col, valid)
        d = [cuda.to_device(a) for a in (cand, white, black)]
        gcol0 = cuda.device_array((h, w), np.int32)
        gel = cuda.device_array((h, w), np.bool_)
        grid = (h * w + vk.TPB - 1) // vk.TPB
        vk.eligible_column[grid, vk.TPB](d[0], d[1], d[2], scale, min_c, gcol0, gel)
        gcol, gval = cuda.device_array((h, w), np.int32), cuda.device_array((h, w), np.bool_)
        vk.support_mask[grid, vk.TPB](gcol0, cuda.to_device(conf), gel, use, float(t_high), 3, 1, min_conf, t_low,
                                      gcol, gval)
        for a, b in ((col0, gcol0), (elig, gel), (col, gcol), (valid, gval)):
            ok &= np.array_equal(a, b.copy_to_host())
    emit(name, ok, f"{int(valid.sum())} valid")


def check_refit_kernels(name, code_name, *, h, w):
    """refit.refine_levels / initial_levels / normalise against edge.decode.levels on the same inputs."""
    from numba import cuda

    from edge.decode import levels
    from edge.decode.backends.cuda import refit as rk
    from edge.decode.inputs import validate
    from edge.decode.backends.cuda.device import device_tables

    code = get_code(code_name)
    cap, white, black = capture(code, h, w, dtype=np.uint16, dark=0.2)
    st = validate(cap.frames, white, black, code)  # normalised float32, as the level stage does
    s32 = np.float32(st.scale)
    f, wn, bn = (st.frames.astype(np.float32) * s32, st.white.astype(np.float32) * s32,
                 st.black.astype(np.float32) * s32)
    wi, bi = levels.initial_levels(f, wn, bn)
    rng = np.random.default_rng(3)
    col = rng.integers(-1, code.size, (h, w)).astype(np.int32)
    wr, br = levels.refine_levels(f, wi, bi, code, col)
    scale = np.float32(1.0 / 65535)
    gf = cuda.device_array(f.shape, np.float32)
    gw, gb = cuda.device_array((h, w), np.float32), cuda.device_array((h, w), np.float32)
    grid = (h * w + rk.TPB - 1) // rk.TPB
    rk.normalise[grid, rk.TPB](cuda.to_device(cap.frames), cuda.to_device(white), cuda.to_device(black), scale, gf, gw, gb)
    ok = np.array_equal(gf.copy_to_host(), f) and np.array_equal(gw.copy_to_host(), wn)
    rk.initial_levels[grid, rk.TPB](gf, gw, gb)
    ok_init = np.array_equal(gw.copy_to_host(), wi) and np.array_equal(gb.copy_to_host(), bi)
    tb = device_tables(code)
    cand = np.stack([col, col, col], -1)
    ow, ob = cuda.device_array((h, w), np.float32), cuda.device_array((h, w), np.float32)
    rk.refine_levels[grid, rk.TPB](gf, gw, gb, tb["xtab"], tb["sx"], tb["sxx"], cuda.to_device(cand), ow, ob)
    ok_ref = np.array_equal(ow.copy_to_host(), wr) and np.array_equal(ob.copy_to_host(), br)
    emit(name, ok and ok_init and ok_ref, f"normalise {ok} initial {ok_init} refine {ok_ref}; "
                                          f"{int((~(wn > bn)).sum())} pixels with white <= black")


def check_staging(name, code_name, *, h, w):
    from edge.decode.backends.cuda.staging import Staging
    from edge.decode.settings import DEFAULT_SETTINGS

    code = get_code(code_name)
    cap, white, black = capture(code, h, w, band_center=4, dark=0.05)
    # the device's whole decode runs the contrast / confidence rule (the "error" rule's posterior
    # runs on the host after the device search, through decode())
    s = DEFAULT_SETTINGS.replace(backend="cuda", validity="confidence")
    st = Staging(code.n, (h, w), np.uint8)
    ok = True
    for _ in range(3):  # three stacks through the two buffer sets
        for i in range(code.n):
            st.put(i, cap.frames[i])
        st.put_white(white)
        st.put_black(black)
        got = st.decode(st.commit(), code, s, min_disparity=0, max_disparity=8)
        ref = decode(cap.frames, white, black, code, min_disparity=0, max_disparity=8, validity="confidence")
        ok &= all(np.array_equal(getattr(ref, f), getattr(got, f)) for f in FIELDS)
    try:
        st.put(0, cap.frames[0])
        st.commit()
        ok = False
    except ValueError as e:
        ok &= "never put" in str(e)
    emit(name, ok, "")


def check_runtime_pipeline(name):
    """The runtime's DepthPipeline with ``[decoder] backend = "cuda"`` decodes arrays through
    `Staging` and returns the CPU pipeline's columns / confidence / valid mask (and nothing else:
    candidates / distances are not downloaded, None)."""
    from _service_helpers import load_test_profile

    from edge.decode.backends.cuda import staging
    from edge.runtime.pipeline import DepthPipeline

    cpu_pipe = DepthPipeline(load_test_profile(decoder=CONFIDENCE_RULE))
    gpu_pipe = DepthPipeline(load_test_profile(decoder={**CONFIDENCE_RULE, "backend": "cuda"}))
    code = cpu_pipe.code
    h, w = 3, 24
    cap, white, black = capture(code, h, w, band_center=-30, dark=0.05)
    ref = cpu_pipe.decode(cap.frames, white, black)
    staging._CACHE.clear()
    got = gpu_pipe.decode(cap.frames, white, black)
    ok = all(np.array_equal(getattr(ref, f), getattr(got, f)) for f in HOST) and len(staging._CACHE) == 1
    ok &= got.candidates is None and got.distances is None and int(ref.valid.sum()) > 0
    emit(name, ok, f"code {code.name}, staged {len(staging._CACHE)}, valid {int(ref.valid.sum())}")


HOST = ("column", "confidence", "valid")
#: The runtime checks of the device's whole decode and of staging run the "confidence" rule (the
#: test profile's default is the library's "error" rule: device search, host posterior, no staging;
#: `check_runtime_error_rule`).
CONFIDENCE_RULE = {"validity": "confidence"}


def check_runtime_error_rule(name):
    """The test profile as it is (the library's defaults: the "error" rule) with backend "cuda":
    frames are staged, and the device's error rule gives the CPU pipeline's column, confidence,
    valid mask and error probability, and a whole stack's depth result equals the CPU's (error
    image included), staged or uploaded whole."""
    from _service_helpers import load_test_profile

    from edge.runtime.assembly import StackAssembler
    from edge.runtime.pipeline import DepthPipeline

    cpu_pipe = DepthPipeline(load_test_profile())
    gpu_pipe = DepthPipeline(load_test_profile(decoder={"backend": "cuda"}))
    ok = cpu_pipe.rule == gpu_pipe.rule == "error" and gpu_pipe.stager is not None and gpu_pipe.on_frame is not None
    cap, white, black = capture(cpu_pipe.code, 3, 24, band_center=-30, dark=0.05)
    ref = cpu_pipe.decode(cap.frames, white, black)
    got = gpu_pipe.decode(cap.frames, white, black)
    ok &= all(np.array_equal(getattr(ref, f), getattr(got, f)) for f in HOST) and error_agrees(ref.error, got.error)
    m = len(gpu_pipe.schedule)
    same = 0
    staged = 0
    for k, images in enumerate(stacks_for(gpu_pipe.code, 2)):
        asm = StackAssembler(gpu_pipe.schedule)
        if k == 1:  # the second stack arrives through the capture hook: staged frame by frame
            asm.on_frame = gpu_pipe.on_frame
        stack = None
        for f in stack_frames(gpu_pipe, images, k, k * m):
            stack = asm.push(f) or stack
        a, b = cpu_pipe.process(stack), gpu_pipe.process(stack)
        staged += int(b.stats.get("gpu_stacks_staged", 0))
        same += same_result(a, b) and a.error is not None and a.error.tobytes() == b.error.tobytes()
    ok &= same == 2 and staged == 1
    emit(name, ok, f"valid {int(ref.valid.sum())}, stacks equal {same} of 2, staged {staged}")


class Downloads:
    """Counts the arrays `pipeline.finish` copies back (the `pipeline.to_host` seam)."""

    def __init__(self):
        from edge.decode.backends.cuda import pipeline as gp

        self.gp, self.real, self.names, self.bytes = gp, gp.to_host, [], 0

    def __enter__(self):
        def counting(name, array, stream=0):
            out = self.real(name, array, stream)
            self.names.append(name)
            self.bytes += out.nbytes
            return out

        self.gp.to_host = counting
        return self

    def __exit__(self, *exc):
        self.gp.to_host = self.real


def check_reduced_download(name):
    """The runtime's GPU path copies back only column, confidence and valid (candidates /
    distances never leave the device), with the CPU's values; the library's decode(...,
    backend="cuda") still downloads and returns the full Decoded; "list+median" downloads what its
    host filters need but not the distances."""
    from _service_helpers import load_test_profile

    from edge.runtime.pipeline import DepthPipeline

    code = get_code("ecc-22-10")
    h, w = 3, 24
    cap, white, black = capture(code, h, w, band_center=-30, dark=0.05)
    details, ok = [], True
    for method in ("soft", "list+median"):
        cpu_pipe = DepthPipeline(load_test_profile(decoder={**CONFIDENCE_RULE, "method": method}))
        gpu_pipe = DepthPipeline(load_test_profile(decoder={**CONFIDENCE_RULE, "method": method, "backend": "cuda"}))
        ref = cpu_pipe.decode(cap.frames, white, black)
        with Downloads() as dl:
            got = gpu_pipe.decode(cap.frames, white, black)
        expect = ["column", "confidence", "valid"] if method == "soft" else ["candidates", "confidence", "column0",
                                                                            "eligible"]
        same = all(np.array_equal(getattr(ref, f), getattr(got, f)) for f in HOST)
        ok &= same and sorted(dl.names) == sorted(expect) and got.candidates is None and got.distances is None
        ok &= dl.bytes == got.stats["download_bytes"] and int(ref.valid.sum()) > 0
        details.append(f"{method}: downloaded {dl.names} ({dl.bytes} B), same {same}")
        with Downloads() as full:  # the library's decode: the whole Decoded, bit for bit
            lib = decode(cap.frames, white, black, code, backend="cuda", method=method, min_disparity=-44,
                         max_disparity=-16, columns=cpu_pipe.columns, validity="confidence")
        lref = decode(cap.frames, white, black, code, method=method, min_disparity=-44, max_disparity=-16,
                      columns=cpu_pipe.columns, validity="confidence")
        ok &= "distances" in full.names and "candidates" in full.names and full.bytes > dl.bytes
        ok &= all(np.array_equal(getattr(lref, f), getattr(lib, f)) for f in FIELDS)
        details.append(f"library: {full.names} ({full.bytes} B)")
    emit(name, ok, "; ".join(details))


def stack_frames(pipe, images, stack, seq0):
    """Frame objects of one stack (schedule order) with these (n + 2, H, W) images."""
    from edge.sensors.base import Frame

    return [Frame(image=images[i], sequence=seq0 + i, timestamp_ns=1000 * (seq0 + i), exposure_us=100.0,
                  projector_frame=int(pipe.schedule[i]), stack=stack) for i in range(len(pipe.schedule))]


def stacks_for(code, count, h=3, w=24):
    """`count` different (n + 2, H, W) uint8 stacks (seeds 10..), some pixels dark."""
    out = []
    for k in range(count):
        cap, white, black = capture(code, h, w, band_center=-30, dark=0.05, seed=10 + k)
        out.append(np.concatenate([cap.frames, white[None], black[None]]))
    return out


def same_result(a, b) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("column", "confidence", "depth_mm"))


def pipes():
    from _service_helpers import load_test_profile

    from edge.runtime.pipeline import DepthPipeline

    return (DepthPipeline(load_test_profile(decoder=CONFIDENCE_RULE)),
            DepthPipeline(load_test_profile(decoder={**CONFIDENCE_RULE, "backend": "cuda"})))


def check_staged_frames(name):
    """Frames fed one by one through the assembler's hook: a staged stack decodes to the CPU
    pipeline's depth, column and confidence, identical to the whole-stack upload of the same
    stack; the decode downloads only column / confidence / valid."""
    from edge.runtime.assembly import StackAssembler

    cpu_pipe, gpu_pipe = pipes()
    assert gpu_pipe.on_frame is not None and cpu_pipe.on_frame is None
    asm = StackAssembler(gpu_pipe.schedule, on_frame=gpu_pipe.on_frame)
    ok, details = True, []
    m = len(gpu_pipe.schedule)
    for k, images in enumerate(stacks_for(gpu_pipe.code, 3)):
        stack = None
        for f in stack_frames(gpu_pipe, images, k, k * m):
            stack = asm.push(f) or stack
        ref = cpu_pipe.process(stack)
        with Downloads() as dl:
            got = gpu_pipe.process(stack)
        whole = gpu_pipe.decode(images[:-2], images[-2], images[-1])  # the whole-stack upload
        ok &= same_result(ref, got) and got.stats == {"gpu_stacks_staged": 1, "gpu_stacks_uploaded_whole": 0}
        ok &= np.array_equal(np.where(whole.valid, whole.column, -1), got.column)
        ok &= sorted(dl.names) == ["column", "confidence", "valid"] and int((got.column >= 0).sum()) > 0
        details.append(f"stack {k}: {got.stats}, valid {int((got.column >= 0).sum())}")
    st = gpu_pipe.stager
    ok &= st.counters["stacks_taken"] == 3 and st.counters["frames_skipped"] == 0 and not st.error
    emit(name, ok, "; ".join(details) + f"; counters {st.counters}")


def check_staged_fallback(name):
    """Stacks that were not staged decode by whole-stack upload, with the same results: a stack
    with a dropped frame (never decoded: the next one is staged), a stack re-assembled from new
    Frame objects, a stack whose first frames the hook never saw, a stack captured while the
    only set was busy, and a complete set reclaimed by a newer stack; a stack of another frame
    shape re-allocates the idle sets and is staged."""
    from edge.decode.backends.cuda.staging import FrameStager
    from edge.runtime.assembly import Stack, StackAssembler

    cpu_pipe, gpu_pipe = pipes()
    m = len(gpu_pipe.schedule)
    imgs = stacks_for(gpu_pipe.code, 6)
    asm = StackAssembler(gpu_pipe.schedule, on_frame=gpu_pipe.on_frame)
    ok, details = True, []

    def push(frames):
        out = None
        for f in frames:
            out = asm.push(f) or out
        return out

    def expect(stack, staged, label):
        nonlocal ok
        got = gpu_pipe.process(stack)
        good = same_result(cpu_pipe.process(stack), got) and got.stats["gpu_stacks_staged"] == int(staged)
        ok &= good
        details.append(f"{label}: {'staged' if staged else 'whole'} {good}")

    # 1. a dropped frame: the assembler drops stack 0, stack 1 is staged
    fr = stack_frames(gpu_pipe, imgs[0], 0, 0)
    ok &= push(fr[:5] + fr[6:]) is None
    expect(push(stack_frames(gpu_pipe, imgs[1], 1, m)), True, "after a dropped stack")
    # 2. re-assembled (new Frame objects, same images): not the staged frames -> whole upload
    fr = stack_frames(gpu_pipe, imgs[2], 2, 2 * m)
    push(fr)
    expect(Stack(2, tuple(stack_frames(gpu_pipe, imgs[2], 2, 2 * m)), 0), False, "re-assembled")
    # 3. the hook attached mid-stack (a pipeline change): whole upload
    asm.on_frame = None
    fr = stack_frames(gpu_pipe, imgs[3], 3, 3 * m)
    push(fr[:4])
    asm.on_frame = gpu_pipe.on_frame
    expect(push(fr[4:]), False, "hook from frame 4 on")
    # 4. one set, busy while the next stack is captured; then a complete set reclaimed
    gpu_pipe.stager = FrameStager(m, sets=1)
    asm.on_frame = gpu_pipe.stager.put
    a = push(stack_frames(gpu_pipe, imgs[4], 4, 4 * m))
    k = gpu_pipe.stager.take(a.frames)  # the decode thread holds the set
    b = push(stack_frames(gpu_pipe, imgs[5], 5, 5 * m))
    ok &= k == 0 and gpu_pipe.stager.counters["frames_skipped"] == m
    gpu_pipe.stager.release(k)
    expect(b, False, "captured while the set was busy")
    c = push(stack_frames(gpu_pipe, imgs[0], 6, 6 * m))
    d = push(stack_frames(gpu_pipe, imgs[1], 7, 7 * m))  # reclaims c's complete set
    ok &= gpu_pipe.stager.counters["sets_reclaimed"] == 1
    expect(c, False, "set reclaimed")
    expect(d, True, "the reclaiming stack")
    # 5. frames of another shape: the idle sets are re-allocated for it
    e = push(stack_frames(gpu_pipe, stacks_for(gpu_pipe.code, 1, w=20)[0], 8, 8 * m))
    ok &= gpu_pipe.stager.shape == (3, 20)
    expect(e, True, "new frame shape")
    emit(name, ok, "; ".join(details))


def check_staged_threads(name):
    """A capture thread feeds frames (assembler + hook) while the decode thread decodes: every
    stack's result equals the CPU pipeline's, the sets are reused (3 sets, 6 stacks).  Paced
    run: capture starts stack k once stack k - 2 is decoded, so every stack is staged while
    another decodes; free run: capture as fast as it can, stacks fall back as sets run out."""
    import threading

    from edge.runtime.assembly import StackAssembler
    from edge.runtime.stack_queue import Closed, LatestQueue

    cpu_pipe, _ = pipes()
    imgs = stacks_for(cpu_pipe.code, 6)
    m = len(cpu_pipe.schedule)
    ok, details = True, []
    for paced in (True, False):
        _, gpu_pipe = pipes()
        asm = StackAssembler(gpu_pipe.schedule, on_frame=gpu_pipe.on_frame)
        queue = LatestQueue(8)
        done = threading.Semaphore(0)
        results, errors = {}, []

        def capture_loop():
            try:
                for k, images in enumerate(imgs):
                    if paced and k >= 2:
                        done.acquire()  # stack k - 2 decoded: its set is free again
                    for f in stack_frames(gpu_pipe, images, k, k * m):
                        stack = asm.push(f)
                        if stack is not None:
                            queue.put(stack)
            except Exception as exc:
                errors.append(exc)
            finally:
                queue.close()

        def decode_loop():
            try:
                while True:
                    try:
                        stack = queue.get(1.0)
                    except Closed:
                        return
                    if stack is not None:
                        results[stack.stack] = (stack, gpu_pipe.process(stack))
                        done.release()
            except Exception as exc:
                errors.append(exc)

        threads = [threading.Thread(target=capture_loop), threading.Thread(target=decode_loop)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(300)
        staged = sum(r.stats["gpu_stacks_staged"] for _, r in results.values())
        good = not errors and len(results) == len(imgs)
        good &= all(same_result(cpu_pipe.process(s), r) for s, r in results.values())
        if paced:
            good &= staged == len(imgs) and gpu_pipe.stager.counters["frames_skipped"] == 0
        good &= not any(gpu_pipe.stager._busy)
        ok &= good
        details.append(f"{'paced' if paced else 'free'}: {len(results)} stacks, {staged} staged, ok {good}, "
                       f"{gpu_pipe.stager.counters} {errors[:1]}")
    emit(name, ok, "; ".join(details))


def check_service_staged(name):
    """The Service (capture thread + its one decode thread) with backend "cuda": the pinned sets
    are allocated before the first frame (``prepare_capture``), the assembler hands frames to
    the pipeline's stager, and a live config change (min_confidence, sent with the first frame)
    keeps the staged frames (``continue_from``): every stack decodes from its staged set (status
    ``gpu_stacks_staged``) and the published columns equal the CPU pipeline's with the new
    settings."""
    from _service_helpers import load_test_profile

    from edge.runtime.pipeline import DepthPipeline
    from edge.runtime.service import Service
    from edge.sensors.base import EndOfStream, SensorInfo

    class NoWarmUp(DepthPipeline):
        def warm_up(self):
            return 0.0

    small = {"width": 24, "height": 3}  # the service refuses frames of another size than the profile camera's
    profile = load_test_profile(decoder={**CONFIDENCE_RULE, "backend": "cuda"}, camera=small)
    pipe = NoWarmUp(profile)
    imgs = stacks_for(pipe.code, 3)
    m = len(pipe.schedule)
    frames = [f for k, images in enumerate(imgs) for f in stack_frames(pipe, images, k, k * m)]
    seen = {}

    class ListSensor:
        info = SensorInfo(name="list", width=24, height=3, bits=8, fps=0.0, n_code_frames=pipe.n)

        def __init__(self):
            self.frames = list(frames)

        def start(self):
            pass

        def read(self, timeout_s=1.0):
            if not self.frames:
                raise EndOfStream()
            if len(self.frames) == len(frames):
                seen["prepared"] = svc.pipeline.stager.shape == (3, 24)
                svc.update_config({"decoder": {"min_confidence": 0.6}})
            time.sleep(0.01)
            return self.frames.pop(0)

        def stop(self):
            pass

    class Sink:
        def __init__(self):
            self.results = []

        def on_result(self, r):
            self.results.append(r)

        def on_status(self, s):
            pass

        def close(self):
            pass

    sink = Sink()
    svc = Service(profile, ListSensor(), sinks=[sink], queue_capacity=8, pipeline_factory=NoWarmUp,
                  warm_variants=False)
    status = svc.run(stacks=3)
    cpu_pipe = DepthPipeline(load_test_profile(decoder={**CONFIDENCE_RULE, "min_confidence": 0.6}, camera=small))
    old_pipe = DepthPipeline(load_test_profile(decoder=CONFIDENCE_RULE, camera=small))
    good = len(sink.results) == 3 and status.get("gpu_stacks_staged") == 3 and seen.get("prepared")
    differs = False
    for r in sink.results:
        images = imgs[r.stack]
        ref = cpu_pipe.decode(images[:-2], images[-2], images[-1])
        old = old_pipe.decode(images[:-2], images[-2], images[-1])
        good &= np.array_equal(np.where(cpu_pipe.validity(ref), ref.column, -1), r.column)
        differs |= not np.array_equal(ref.valid, old.valid)
    emit(name, good and differs, f"{len(sink.results)} results, staged {status.get('gpu_stacks_staged')}, whole "
                                 f"{status.get('gpu_stacks_uploaded_whole')}, prepared {seen.get('prepared')}, "
                                 f"settings matter {differs}, errors {status.get('errors')!r}")


def main() -> int:
    if gpu.SIM:
        yield_while_polled()
    emit("resolve-auto", resolve("auto") == "cuda" and gpu.is_available(), resolve("auto"))
    s = (600, 700) if FULL else (2, 16)  # all-codeword searches
    b = (120, 160) if FULL else (3, 24)  # band searches, decode()
    band = (True, 0, 127) if FULL else (True, -4, 12)
    checks = [
        ("soft-all-ecc-22-10-uint8", lambda: check_search("soft-all-ecc-22-10-uint8", "ecc-22-10", h=s[0], w=s[1], brute=True)),
        ("soft-all-gray-10-inverse", lambda: check_search("soft-all-gray-10-inverse", "gray-10", h=s[0], w=s[1],
                                                          inverse=True, brute=True)),
        # float32 with the all-codeword kernel restricted to a band: the CPU reference is then the
        # float32 band kernel the refit checks compile anyway (CI cost on a cold numba cache)
        ("soft-all-ecc-22-10-float32-normalized-columns", lambda: check_search(
            "soft-all-ecc-22-10-float32-normalized-columns", "ecc-22-10", h=b[0], w=b[1], dtype=np.float32,
            metric=METRIC_NORMALIZED, columns=300, band=band, path="all")),
        ("soft-band-ecc-22-10-uint16", lambda: check_search("soft-band-ecc-22-10-uint16", "ecc-22-10", h=b[0], w=b[1],
                                                            dtype=np.uint16, band=band, brute=True)),
        ("soft-band-ecc-22-10-inverse-stripe", lambda: check_search(
            "soft-band-ecc-22-10-inverse-stripe", "ecc-22-10", h=b[0], w=b[1], inverse=True, band=band, stripe=2,
            columns=500)),
        ("soft-band-gray-10-bitdepth-normalized", lambda: check_search(
            "soft-band-gray-10-bitdepth-normalized", "gray-10", h=b[0], w=b[1], dtype=np.uint16, band=band,
            metric=METRIC_NORMALIZED, bit_depth=16)),
        ("soft-all-restricted-to-band", lambda: check_search("soft-all-restricted-to-band", "ecc-22-10", h=b[0],
                                                             w=b[1], band=band, path="all")),
        ("soft-nary3-6", lambda: check_search("soft-nary3-6", "nary3-6", h=s[0], w=s[1], band=band)),
        ("hard-metric-search-gray-10", lambda: check_search("hard-metric-search-gray-10", "gray-10", h=s[0], w=s[1],
                                                            metric=METRIC_HARD)),
        ("hard-ecc-22-10", lambda: check_hard("hard-ecc-22-10", "ecc-22-10", h=b[0], w=b[1])),
        ("hard-ecc-22-10-inverse-band", lambda: check_hard("hard-ecc-22-10-inverse-band", "ecc-22-10", h=b[0], w=b[1],
                                                           inverse=True, band=band)),
        ("hard-gray-10", lambda: check_hard("hard-gray-10", "gray-10", h=s[0], w=s[1])),
        ("validity", lambda: check_validity("validity", h=b[0] * 3, w=b[1])),
        ("refit-kernels-ecc-22-10", lambda: check_refit_kernels("refit-kernels-ecc-22-10", "ecc-22-10", h=b[0], w=b[1])),
        ("refit-kernels-rs16-15-4", lambda: check_refit_kernels("refit-kernels-rs16-15-4", "rs16-15-4", h=b[0], w=b[1])),
        ("decode-soft", lambda: check_decode("decode-soft", "ecc-22-10", h=b[0], w=b[1])),
        ("decode-hard", lambda: check_decode("decode-hard", "ecc-22-10", h=b[0], w=b[1], method="hard")),
        ("decode-list+median", lambda: check_decode("decode-list+median", "ecc-22-10", h=b[0], w=b[1],
                                                    method="list+median")),
        ("decode-soft-refit", lambda: check_decode("decode-soft-refit", "ecc-22-10", h=b[0], w=b[1], levels="refit")),
        ("decode-hard-refit-uint16", lambda: check_decode("decode-hard-refit-uint16", "gray-10", h=b[0], w=b[1],
                                                          dtype=np.uint16, method="hard", levels="refit")),
        ("decode-soft-inverse-nocheck", lambda: check_decode("decode-soft-inverse-nocheck", "gray-10", h=b[0], w=b[1],
                                                             inverse=True, spatial_check=False)),
        ("confidence-fit-soft", lambda: check_confidence_fit("confidence-fit-soft", "ecc-22-10", h=24, w=24)),
        ("confidence-fit-soft-refit", lambda: check_confidence_fit("confidence-fit-soft-refit", "ecc-22-10", h=24,
                                                                   w=24, levels="refit")),
        ("confidence-fit-list+median", lambda: check_confidence_fit("confidence-fit-list+median", "ecc-22-10", h=24,
                                                                    w=24, method="list+median")),
        ("error-rule-ecc-22-10-band", lambda: check_error_rule("error-rule-ecc-22-10-band", "ecc-22-10", h=b[0],
                                                               w=b[1])),
        ("error-rule-ecc-22-10-all", lambda: check_error_rule("error-rule-ecc-22-10-all", "ecc-22-10", h=s[0], w=s[1],
                                                              band=False)),
        ("error-rule-gray-10-inverse-band", lambda: check_error_rule("error-rule-gray-10-inverse-band", "gray-10",
                                                                     h=b[0], w=b[1], inverse=True)),
        ("error-rule-ecc-22-10-inverse-all", lambda: check_error_rule(
            "error-rule-ecc-22-10-inverse-all", "ecc-22-10", h=s[0], w=s[1], inverse=True, band=False)),
        ("error-rule-gray-10-uint16-median", lambda: check_error_rule(
            "error-rule-gray-10-uint16-median", "gray-10", h=b[0], w=b[1], dtype=np.uint16, method="list+median")),
        ("error-rule-ecc-22-10-hard-calibration", lambda: check_error_rule(
            "error-rule-ecc-22-10-hard-calibration", "ecc-22-10", h=b[0], w=b[1], method="hard", levels="calibration")),
        ("error-rule-nary3-6", lambda: check_error_rule("error-rule-nary3-6", "nary3-6", h=b[0], w=b[1])),
        ("error-rule-ecc-22-10-fitted", lambda: check_error_rule("error-rule-ecc-22-10-fitted", "ecc-22-10", h=24,
                                                                 w=24, fitted=True)),
        ("error-rule-reduced-download", lambda: check_error_rule_reduced("error-rule-reduced-download")),
        ("error-rule-ecc-22-10-sgm", lambda: check_error_rule("error-rule-ecc-22-10-sgm", "ecc-22-10", h=b[0], w=b[1],
                                                              method="sgm")),
        ("staging", lambda: check_staging("staging", "ecc-22-10", h=b[0], w=b[1])),
        ("runtime-pipeline", lambda: check_runtime_pipeline("runtime-pipeline")),
        ("reduced-download", lambda: check_reduced_download("reduced-download")),
        ("staged-frames", lambda: check_staged_frames("staged-frames")),
        ("staged-fallback", lambda: check_staged_fallback("staged-fallback")),
        ("staged-threads", lambda: check_staged_threads("staged-threads")),
        ("service-staged", lambda: check_service_staged("service-staged")),
        ("runtime-error-rule", lambda: check_runtime_error_rule("runtime-error-rule")),
        # one thread per pixel refits hundreds of tail words: a few pixels, or the simulator takes minutes
        ("posterior-prior-ecc-22-10", lambda: check_posterior_prior("posterior-prior-ecc-22-10", "ecc-22-10", h=1,
                                                                    w=12)),
        ("posterior-prior-ecc-22-10-inverse", lambda: check_posterior_prior(
            "posterior-prior-ecc-22-10-inverse", "ecc-22-10", h=1, w=12, inverse=True, a=2e-3)),
        ("prior-cost", lambda: check_prior_cost("prior-cost")),
    ]
    only = [a for a in sys.argv[1:] if not a.startswith("--")]
    for name, fn in checks:
        if only and name not in only:
            continue
        t0 = time.perf_counter()
        try:
            fn()
        except Exception:
            emit(name, False, traceback.format_exc()[-1500:])
        print(json.dumps({"timing": name, "seconds": round(time.perf_counter() - t0, 2)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

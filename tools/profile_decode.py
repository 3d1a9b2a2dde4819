"""Where `decode()`'s time goes under the default error rule, stage by stage, and what the
error rule's tail mass costs and on which pixels.

    python tools/profile_decode.py [--repeats 5] [--height 600 --width 700] [--seed 0] [--real DIR]

Inputs: `tools/bench_decode.py`'s two 600 x 700 captures of ecc-22-10 (the high-SNR "easy" one
and the "hard" regime: fixed total exposure, ambient = projector, 12-bit), each decoded over all
codewords and in its disparity band, with `decode()`'s defaults.

Stage table: the median wall time of each stage that `edge.decode.decoder._decode_error_rule`
calls (split levels, the float32 copy of the frames for the search, the candidate search, the
noise fit, the posterior, and the host's goodness-of-fit test and method: `publish_error_rule`), timed by wrapping the decoder module's references to them for the
duration of the run (nothing else is changed), next to the median of the whole call.

Search table: the search's counters of those decodes (`Decoded.stats`): its path, codewords
evaluated per pixel, the share of pixels the skip margin finished and the share it finished
alone after D = 0 in a lane block that did not skip its lightest weight class (both of all pixels).

Tail table (hard regime, all codewords): the tail mass (`posterior._tail_mass`) is due on the
pixels whose third candidate is not negligible and whose top three leave P(confused) below 1/2
(`posterior._posterior`'s mask, read where `posterior._tail_pass` receives it); the table gives how many pixels that is, how
many of them end with P(wrong) >= 1/2, and how many have P(not lit) >= 1/2, where
`posterior._tail_pass` leaves the tail out (P(wrong) is >= 1/2 whatever it adds).  It then times
`posterior()` alone as it is and with no tail at all (a binary code without tail tables: a
timing, not a decoder).

Real-capture table (``--real``, where present): the real Gray-code capture with `decode()`'s
defaults, which with inverse frames run the "confidence" rule: the whole call, the search, the
goodness-of-fit test (`decoder.confidence_fit`) and its two parts, and the whole call without the
test (the rule as it was before it), as a ratio; then the search's counters (codeword costs
evaluated per pixel, the shares of pixels that needed the lane search's second weight class and
whose ties at cost 0 it resolved directly).  Then the same capture under the error rule, which
`decode()` runs by default on pattern frames alone: the stage table's columns for the pattern
frames alone and for pattern + inverse frames with ``validity="error"``, the time of the tail
pass inside the posterior (`posterior._tail_pass`), the share of pixels whose tail mass it sums
(due, and P(not lit) below 1/2) and the share of those that end published.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_decode import make_hard_input, make_input  # noqa: E402
from real_data import REAL_CAPTURE  # noqa: E402

import edge.decode.decoder as decoder  # noqa: E402
import edge.decode.posterior as posterior  # noqa: E402
from edge.decode import decode  # noqa: E402

#: The decoder module's stage functions that are timed (`decoder._decode_error_rule`'s calls).
STAGES = ("split_levels", "split_capture", "search_candidates", "fit_noise", "posterior", "publish_error_rule")


#: The confidence rule's stages timed on the real capture (`decoder._decode`), and the two parts
#: of its goodness-of-fit test (`decoder.confidence_fit`: the noise fit, the test of the published
#: columns), which are inside confidence_fit's time.
CONFIDENCE_STAGES = ("search_candidates", "confidence_fit")
FIT_PARTS = ("fit_noise", "fit_published")
#: The real capture (OpenCV Gray-code layout, 1024 x 768 projector) beside the repository.
REAL = REAL_CAPTURE


@contextlib.contextmanager
def stage_timer(seconds: dict[str, list[float]], names: tuple[str, ...] = STAGES):
    """Wrap ``names`` in `edge.decode.decoder` so that each call appends its wall seconds to
    ``seconds[name]``; the originals are restored on exit."""
    originals = {name: getattr(decoder, name) for name in names}

    def timed(name, fn):
        def call(*args, **kwargs):
            t0 = time.perf_counter()
            out = fn(*args, **kwargs)
            seconds.setdefault(name, []).append(time.perf_counter() - t0)
            return out
        return call

    try:
        for name, fn in originals.items():
            setattr(decoder, name, timed(name, fn))
        yield
    finally:
        for name, fn in originals.items():
            setattr(decoder, name, fn)


def median_ms(fn, repeats: int) -> float:
    fn()  # compile or load the kernels, fill the caches
    wall = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        wall.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(wall)


def stage_rows(label: str, call, repeats: int) -> dict:
    """One row of the stage table; returns the search's counters of the call (`Decoded.stats`)."""
    searched = call().stats
    seconds: dict[str, list[float]] = {}
    with stage_timer(seconds):
        total = median_ms(call, repeats)
    parts = {k: 1e3 * statistics.median(v[1:]) for k, v in seconds.items()}  # v[0]: the warm-up call
    rest = total - sum(parts.values())
    cells = " | ".join(f"{parts.get(k, 0.0):.1f}" for k in STAGES)
    print(f"| {label} | {total:.1f} | {cells} | {rest:.1f} |")
    return searched


def search_rows(rows: list[tuple[str, dict, int]]) -> None:
    """The search's counters of the stage table's decodes: path, codewords (band: candidate
    columns) evaluated per pixel, the share of pixels finished by the skip margin and the share
    finished by it alone after D = 0 in a lane block that did not skip (the lane path; both
    shares of all pixels)."""
    print("\nThe search of those decodes:\n")
    print("| input | path | evaluated / pixel | finished by the margin | finished alone |")
    print("|---|---|---|---|---|")
    for label, st, pixels in rows:
        finished = st.get("margin_pixels")
        alone = st.get("margin_lanes")
        print(f"| {label} | {st.get('path')} | {st.get('evaluated', 0) / pixels:.1f} | "
              f"{'-' if finished is None else f'{finished / pixels:.1%}'} | "
              f"{'-' if alone is None else f'{alone / pixels:.1%}'} |")


def real_rows(folder: Path, repeats: int) -> None:
    """The real capture with `decode()`'s defaults (pattern + inverse frames: the confidence
    rule): the whole call, the search, the goodness-of-fit test and its two parts (medians, ms),
    and the whole call with the test replaced by the identity (the rule as it was before it)."""
    from edge.decode import load_opencv_graycode

    cap = load_opencv_graycode(folder, (1024, 768))
    call = lambda: decode(cap.frames, cap.white, cap.black, cap.code, columns=cap.columns,  # noqa: E731
                          inverse=cap.inverse)
    searched = call().stats
    seconds: dict[str, list[float]] = {}
    with stage_timer(seconds, CONFIDENCE_STAGES + FIT_PARTS):
        total = median_ms(call, repeats)
    parts = {k: 1e3 * statistics.median(v[1:]) for k, v in seconds.items()}  # v[0]: the warm-up call
    fit = decoder.confidence_fit
    decoder.confidence_fit = lambda stack, code, s, best, column: (column, column >= 0, {})
    try:
        without = median_ms(call, repeats)
    finally:
        decoder.confidence_fit = fit
    h, w = cap.white.shape
    print(f"\nReal capture ({folder.name}, {h} x {w}, gray-10 pattern + inverse), decode() defaults "
          f"(the confidence rule); medians in ms:\n")
    print("| whole | search_candidates | confidence_fit | of it: fit_noise | of it: fit_published | "
          "whole without the fit | ratio |")
    print("|---|---|---|---|---|---|---|")
    print(f"| {total:.1f} | {parts['search_candidates']:.1f} | {parts['confidence_fit']:.1f} | "
          f"{parts['fit_noise']:.1f} | {parts['fit_published']:.1f} | {without:.1f} | {total / without:.2f} |")
    print(f"\nThe search (path {searched.get('path')}): {searched.get('evaluated', 0) / (h * w):.1f} codewords "
          f"evaluated per pixel; pixels that needed the second weight class "
          f"{searched.get('second_class_pixels', 0) / (h * w):.2%}, ties at cost 0 resolved directly "
          f"{searched.get('zero_set_pixels', 0) / (h * w):.2%}.")
    real_error_rule_rows(cap, repeats)


def tail_pass_spy(seconds: dict[str, list[float]], seen: dict[str, np.ndarray]):
    """A stand-in for `posterior._tail_pass` that appends its wall seconds to
    ``seconds["tail_pass"]`` and leaves in ``seen["runs"]`` (H, W) bool the pixels it sums the
    tail of (due, and P(not lit) below 1/2), then calls the original."""
    original = posterior._tail_pass

    def spy(*a):
        seen["runs"] = (a[7] != 0) & (not_lit_of(a[11], a[12]) < 0.5)  # due, and P(not lit) below 1/2
        t0 = time.perf_counter()
        original(*a)
        seconds.setdefault("tail_pass", []).append(time.perf_counter() - t0)

    return spy


def real_error_rule_rows(cap, repeats: int) -> None:
    """The real capture under the error rule: pattern frames only (what `decode()` runs by default
    without inverse frames) and pattern + inverse with ``validity="error"``: the whole call, the
    stages (medians, ms), the tail pass inside the posterior (`posterior._tail_pass`), the share
    of pixels whose tail it sums and the share of those that end published."""
    print("\nReal capture under the error rule (`decode()`'s default without inverse frames); medians in ms, "
          "tail_pass inside posterior:\n")
    print("| frames | whole | " + " | ".join(STAGES) + " | of posterior: tail_pass | tail summed on | "
          "of those published |")
    print("|---" * (len(STAGES) + 5) + "|")
    rows = (("pattern only (defaults)", {}), ("pattern + inverse, validity=\"error\"",
                                               {"inverse": cap.inverse, "validity": "error"}))
    for label, kwargs in rows:
        call = lambda: decode(cap.frames, cap.white, cap.black, cap.code, columns=cap.columns, **kwargs)  # noqa: E731
        seconds: dict[str, list[float]] = {}
        seen: dict[str, np.ndarray] = {}
        original = posterior._tail_pass
        posterior._tail_pass = tail_pass_spy(seconds, seen)
        try:
            with stage_timer(seconds):
                total = median_ms(call, repeats)
            published = call().valid
        finally:
            posterior._tail_pass = original
        parts = {k: 1e3 * statistics.median(v[1:]) for k, v in seconds.items()}  # v[0]: the warm-up call
        runs = seen.get("runs", np.zeros(cap.white.shape, bool))  # (none where the code has no tail tables)
        cells = " | ".join(f"{parts.get(k, 0.0):.1f}" for k in STAGES)
        print(f"| {label} | {total:.1f} | {cells} | {parts.get('tail_pass', 0.0):.1f} | {runs.mean():.1%} | "
              f"{published[runs].mean():.1%} |")


def captured_posterior_args(call):
    """The positional and keyword arguments `decode` passes to `posterior` (one call)."""
    seen = {}
    original = decoder.posterior

    def spy(*args, **kwargs):
        seen["args"], seen["kwargs"] = args, kwargs
        return original(*args, **kwargs)

    decoder.posterior = spy
    try:
        call()
    finally:
        decoder.posterior = original
    return seen["args"], seen["kwargs"]


def due_and_not_lit(args, kwargs) -> tuple[np.ndarray, np.ndarray]:
    """From one posterior call: (H, W) bool where the tail mass is due (`posterior._posterior`'s
    mask, as `posterior._tail_pass` receives it) and (H, W) P(not lit) (1 where the gain is not
    finite)."""
    seen = {}
    original = posterior._tail_pass

    def spy(*a):
        seen["due"], seen["idx"], seen["fdr"] = a[7].copy(), a[11].copy(), a[12].copy()
        original(*a)

    posterior._tail_pass = spy
    try:
        posterior.posterior(*args, **kwargs)
    finally:
        posterior._tail_pass = original
    return seen["due"] != 0, not_lit_of(seen["idx"], seen["fdr"])


def not_lit_of(idx: np.ndarray, fdr: np.ndarray) -> np.ndarray:
    """(H, W) float64 P(not lit) from `posterior._tail_pass`'s arguments: the not-lit lookup's
    bin per pixel (idx, -1 where the gain is not finite) and its table (fdr); 1 where idx < 0."""
    return np.where(idx >= 0, fdr[np.maximum(idx, 0)], 1.0)


def tail_rows(code, cap, repeats: int) -> None:
    call = lambda: decode(cap.frames, cap.white, cap.black, code, bit_depth=cap.bit_depth)  # noqa: E731
    args, kwargs = captured_posterior_args(call)
    out = posterior.posterior(*args, **kwargs)
    gated, p_not_lit = due_and_not_lit(args, kwargs)
    dark = p_not_lit >= 0.5
    total = out.error.size
    print(f"pixels {total}; the tail is due on {int(gated.sum())} ({gated.mean():.1%}); of those "
          f"P(wrong) >= 1/2: {(out.error[gated] >= 0.5).mean():.1%}, P(not lit) >= 1/2 (tail left out): "
          f"{dark[gated].mean():.1%}")
    as_is = median_ms(lambda: posterior.posterior(*args, **kwargs), repeats)
    original = posterior._flips
    no_tables = posterior.no_tail_tables()
    posterior._flips = lambda c: no_tables
    try:
        no_tail = median_ms(lambda: posterior.posterior(*args, **kwargs), repeats)
    finally:
        posterior._flips = original
    print("| posterior() | median ms | vs as is |")
    print("|---|---|---|")
    print(f"| as is | {as_is:.1f} | 1.00 |")
    print(f"| no tail anywhere | {no_tail:.1f} | {no_tail / as_is:.2f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5, help="timed calls per row, the median reported (default %(default)s)")
    ap.add_argument("--height", type=int, default=600, help="image height of the inputs in pixels (default %(default)s)")
    ap.add_argument("--width", type=int, default=700, help="image width of the inputs in pixels (default %(default)s)")
    ap.add_argument("--seed", type=int, default=0, help="seed of both inputs (default %(default)s)")
    ap.add_argument("--real", type=Path, default=REAL,
                    help="OpenCV Gray-code capture folder for the real-capture table, skipped if absent "
                         "(default ../shared/data/procam-graycode/capture_0)")
    args = ap.parse_args(argv)
    h, w = args.height, args.width
    code, _, easy = make_input(h, w, 128, args.seed)
    hcode, _, hard, band = make_hard_input(h, w, args.seed)
    print(f"decode() defaults, ecc-22-10, {h} x {w}; stage medians in ms (rest: validation, masks, glue)\n")
    print("| input | whole | " + " | ".join(STAGES) + " | rest |")
    print("|---" * (len(STAGES) + 3) + "|")
    rows = []
    for label, call in (
            ("easy", lambda: decode(easy.frames, easy.white, easy.black, code)),
            ("easy, band [0, 128]", lambda: decode(easy.frames, easy.white, easy.black, code,
                                                   min_disparity=0, max_disparity=128)),
            ("hard", lambda: decode(hard.frames, hard.white, hard.black, hcode, bit_depth=hard.bit_depth)),
            (f"hard, band [{band[0]}, {band[1]}]", lambda: decode(
                hard.frames, hard.white, hard.black, hcode, bit_depth=hard.bit_depth, min_disparity=band[0],
                max_disparity=band[1]))):
        rows.append((label, stage_rows(label, call, args.repeats), h * w))
    search_rows(rows)
    print("\nThe tail mass, hard regime, all codewords:\n")
    tail_rows(hcode, hard, args.repeats)
    if args.real.is_dir():
        real_rows(args.real, args.repeats)
    else:
        print(f"\n(real capture not found at {args.real}: its table is skipped)")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))

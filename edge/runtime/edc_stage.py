"""The adaptive EDC stage of `DepthPipeline` (profile ``edc.rounds`` > 0), on `edge.edc.AdaptiveScan`.

Round 1 is the stack the service already captured (code frames, white, black): the scan checks
every pixel's hard word against the codebook (CRC / syndrome check) and verifies the ones that
pass (and that a passing neighbour supports).  Each further round (at most ``edc.rounds``) asks the
sensor for the scan's next masked frames (``masked_capture(stack, round, frames)``: n masked
patterns + a masked white, projector frame ids carrying the round number): only the projector
columns not claimed by a verified pixel are lit, only rows with an open pixel are lit at all, and
only the open pixels are decoded (a sparse decode over the open-pixel list, `edge.edc._kernels`),
never the full frame.

Output, consistent column and confidence:

* the scan's column map: verified pixels, plus the soft decoder's column of an open pixel where a
  chain of neighbours links it to verified pixels (`AdaptiveScan` ``keep_guess``, the soft
  columns are the round-1 guesses), so EDC never reports fewer correct pixels than the soft
  decode it checks;
* confidence, always that of the published column: the soft decoder's confidence where the
  published column IS the soft decoder's column; 1.0 where it is a verified codeword (CRC /
  syndrome check and neighbour support) that the soft decoder did not give (a later round's
  decode, or a soft-invalid pixel) -- the hard decoder's confidence of an exact codeword (d1 = 0);
  `GUESS_CONFIDENCE` (the lowest valid confidence, 1 on the wire) where it is an unverified
  later-round guess that the soft decoder did not give (only neighbour support vouches for it);
  0 where invalid.

Without a masked-capture path (a backend that cannot re-project) the stage runs round 1 only.
`EdcOutcome` also carries the per-round decode and capture times (the service's status).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np


#: Confidence of a published column that neither the soft decoder gave nor the check verified (a
#: later round's nearest-codeword guess kept by neighbour support): the lowest valid one (1/255).
GUESS_CONFIDENCE = np.float32(1.0 / 255.0)


def published_confidence(column: np.ndarray, verified: np.ndarray, soft_column: np.ndarray,
                         soft_confidence: np.ndarray) -> np.ndarray:
    """float32 (H, W) confidence of each published ``column`` (see module docstring).

    column: (H, W) int32 published columns (-1 invalid); verified: (H, W) bool, the column passed
    the check; soft_column / soft_confidence: (H, W) the soft decoder's column (-1 invalid) and
    its confidence in [0, 1].
    """
    valid = column >= 0
    same = valid & (column == soft_column)
    other = np.where(verified & valid, np.float32(1.0), np.where(valid, GUESS_CONFIDENCE, np.float32(0.0)))
    return np.where(same, soft_confidence, other).astype(np.float32)


@dataclass(frozen=True, eq=False)
class EdcOutcome:
    """Result of the EDC stage for one stack.

    column: (H, W) int32 (-1 invalid); confidence: (H, W) float32 in [0, 1]; rounds: rounds run
    (1 = the check of the stack itself); extra: masked frames captured (capture order);
    round_ms: decode milliseconds of each round (round 1 included); capture_ms: milliseconds
    spent waiting for each masked round's frames; open_pixels: pixels still open after each round;
    verified: (H, W) bool, the published column passed the check (the rest are guesses).
    """

    column: np.ndarray
    confidence: np.ndarray
    rounds: int
    extra: list
    round_ms: tuple[float, ...]
    capture_ms: tuple[float, ...]
    open_pixels: tuple[int, ...]
    verified: np.ndarray | None = None


def _stacked(images: list) -> np.ndarray:
    """(m, H, W) of m frame images without a copy when they are the consecutive planes of one array."""
    base = images[0].base if images else None
    if (isinstance(base, np.ndarray) and base.ndim == 3 and base.shape[0] == len(images)
            and base.flags.c_contiguous
            and all(im.base is base and im.ctypes.data == base[i].ctypes.data for i, im in enumerate(images))):
        return base
    return np.stack(images)


def make_scan(pipeline: Any, height: int, *, rounds: int | None = None):
    """The `AdaptiveScan` of a pipeline's profile (calibrated binarisation, the disparity band);
    rounds: scan rounds at most (default 1 + ``edc.rounds``)."""
    from edge.edc import AdaptiveScan

    p = pipeline.profile
    return AdaptiveScan(pipeline.code, p.projector.width, height, stripe=pipeline.stripe,
                        max_rounds=1 + int(p.edc.rounds) if rounds is None else rounds,
                        binarisation="calibrated",
                        min_contrast=min(p.decoder.min_contrast, 0.999),
                        noise=(p.camera.sigma_r, p.camera.sigma_s),
                        full_scale=pipeline.full_scale,
                        disparity_band=(p.decoder.min_disparity, p.decoder.max_disparity))


def run_adaptive(pipeline: Any, stack: Any, images: np.ndarray, column: np.ndarray, confidence: np.ndarray,
                 masked_capture: Any) -> EdcOutcome:
    """EDC rounds on one stack, by the scan's one driver `edge.edc.AdaptiveScan.run`.

    images: (n + 2, H, W) the stack's code frames, white, black (one array, no copy made);
    column / confidence: (H, W) the soft decoder's column (-1 invalid) and confidence.
    masked_capture: `MaskedCaptureFn` for rounds 2.. (None: round 1, the check of the stack, only).
    """
    n = pipeline.code.n
    h = images.shape[1]
    scan = make_scan(pipeline, h, rounds=1 if masked_capture is None else None)
    capture_ms: list[float] = []
    extra: list = []
    edc_round = 0

    def capture(frames: np.ndarray) -> np.ndarray:
        nonlocal edc_round
        edc_round += 1
        if edc_round == 1:  # round 1 decodes the stack already captured
            return images[: n + 2]
        t0 = time.perf_counter()
        captured = masked_capture(stack.stack, edc_round - 1, frames)
        capture_ms.append((time.perf_counter() - t0) * 1e3)
        extra.extend(captured)
        return _stacked([f.image for f in captured])

    result = scan.run(capture, guess=column)
    round_ms = [r.decode_s * 1e3 for r in result.rounds]
    open_px = [r.failing for r in result.rounds]
    col = np.asarray(result.column, dtype=np.int32)
    verified = np.asarray(result.verified if result.verified is not None else result.round_of > 0, dtype=bool)
    verified &= col >= 0
    conf = published_confidence(col, verified, column, confidence)
    return EdcOutcome(column=col, confidence=conf, rounds=len(result.rounds), extra=extra,
                      round_ms=tuple(round(t, 3) for t in round_ms),
                      capture_ms=tuple(round(t, 3) for t in capture_ms), open_pixels=tuple(open_px),
                      verified=verified)

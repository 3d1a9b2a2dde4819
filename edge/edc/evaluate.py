"""Measurements for the EDC work: error maps against ground truth, adaptive loop vs single pass.

Definitions (all counts in camera pixels):

* single pass: one capture of the code at fixed total exposure; hard decision then the nearest
  codeword (`edge.decode.decode(method="hard")` column, every pixel, no rejection) -- what a
  sensor reports without any error map.  A pixel is WRONG when its column differs from the true
  one or when the projector does not reach it at all (ground truth -1) -- indirect light alone
  produces plausible-looking but meaningless words there.
* error maps (True = reject): EDC (`edge.decode.check`, parameter-free), contrast
  (`contrast_error_map`, white - black < t), and their OR.  caught = wrong pixels rejected / wrong
  pixels; false rejects = good pixels rejected / good pixels.
* adaptive targets: errors a single pass leaves = wrong pixels the single pass reports valid
  (with the loop's shadow floor as its only mask); errors left = wrong pixels valid after the loop;
  wrongly invalidated = pixels correct in the single pass that the loop leaves invalid, as a
  fraction of the single pass's correct pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from edge.codes import Code

from .adaptive import DEFAULT_MIN_CONTRAST, AdaptiveResult, run_adaptive

#: GI scenes of the evaluation with physically plausible parameters (see docs/results/edc/README.md):
#: narrow grooves / a deep bowl of a bright diffuse material (albedo 0.9); interreflection strength
#: 1/(1 - albedo * F) sums the higher bounces of the one-bounce model (F: face-to-face form factor).
GI_SCENES: dict[str, dict[str, Any]] = {
    "v-groove": {"angle_deg": 40.0, "albedo": 0.9, "interreflection": 2.5},
    "v-groove-30": {"angle_deg": 30.0, "albedo": 0.9, "interreflection": 3.0},
    "bowl": {"radius": 0.3, "albedo": 0.9, "interreflection": 6.0},
    "scattering": {"scattering": 0.8},
}


def make_gi_scene(label: str, width: int, height: int, seed: int = 0):
    """Scene ``label`` of `GI_SCENES` (base name before the first '-<digits>' suffix)."""
    from edge.sim import make_scene

    if label not in GI_SCENES:
        raise ValueError(f"unknown GI scene {label!r}; valid: {', '.join(GI_SCENES)}")
    base = "v-groove" if label.startswith("v-groove") else label
    return make_scene(base, width, height, seed=seed, **GI_SCENES[label])


def truth_columns(scene: Any, stripe: int = 1) -> np.ndarray:
    """(H, W) int32 true codeword index (column // stripe), -1 where the projector does not reach."""
    col = np.asarray(scene.column_int)
    return np.where(scene.lit & (col >= 0), col // stripe, -1).astype(np.int32)


@dataclass(frozen=True)
class MapScore:
    """How an error map separates wrong from good pixels."""

    caught: float          # fraction of wrong pixels flagged
    false_reject: float    # fraction of good pixels flagged
    wrong: int
    good: int


def score_map(flags: np.ndarray, wrong: np.ndarray, domain: np.ndarray) -> MapScore:
    """Score a (H, W) bool error map against (H, W) bool wrong pixels over ``domain``."""
    w = wrong & domain
    g = ~wrong & domain
    return MapScore(
        caught=float((flags & w).sum() / max(1, w.sum())), false_reject=float((flags & g).sum() / max(1, g.sum())),
        wrong=int(w.sum()), good=int(g.sum()),
    )


def error_map_roc(scene: Any, camera: Any, code: Code, *, rng: Any = 0,
                  thresholds: np.ndarray | None = None) -> dict[str, Any]:
    """Single pass of ``code``: EDC point, contrast ROC over ``thresholds`` and the combination.

    Returns {"edc": MapScore, "contrast": [MapScore], "combined": [MapScore], "thresholds": array}.
    Domain: every camera pixel (shadow pixels count as wrong when decoded).
    """
    from edge.decode import check, contrast_error_map, decode
    from edge.sim import capture_code

    cap = capture_code(scene, code, camera, rng=rng)
    dec = decode(cap.frames, cap.white, cap.black, code, method="hard", min_contrast=0.0, min_confidence=0.0)
    col = np.asarray(dec.candidates[..., 0] if dec.candidates is not None else dec.column)
    wrong = col != truth_columns(scene)
    domain = np.ones_like(wrong)
    ts = np.linspace(0.0, 0.3, 31) if thresholds is None else np.asarray(thresholds, dtype=float)
    edc = check(cap.frames, cap.white, cap.black, code)
    contrast = [score_map(contrast_error_map(cap.white, cap.black, float(t)), wrong, domain) for t in ts]
    combined = [score_map(edc | contrast_error_map(cap.white, cap.black, float(t)), wrong, domain) for t in ts]
    return {"edc": score_map(edc, wrong, domain), "contrast": contrast, "combined": combined, "thresholds": ts}


@dataclass(frozen=True)
class LoopScore:
    """Adaptive loop vs single pass on one scene."""

    scheme: str
    binarisation: str
    rounds: int
    frames: list[int]
    frames_total: int
    calibration_frames: int
    stop_reason: str
    single_errors: int       # wrong pixels the reference single pass reports valid
    errors_left: int         # wrong pixels valid after the loop
    errors_left_unreached: int  # ... of which the projector does not reach (indirect light only)
    removed: float           # 1 - errors_left / single_errors
    correct_single: int
    wrongly_invalidated: float  # fraction of the single pass's correct pixels left invalid
    valid_fraction: float       # valid pixels / pixels the projector reaches


def score_loop(scene: Any, camera: Any, scheme: Any, *, rng: Any = 0, max_rounds: int = 3,
               binarisation: str = "self", **options: Any) -> tuple[LoopScore, AdaptiveResult]:
    """Run the adaptive loop of ``scheme`` and compare with the reference single pass of the SAME scheme.

    The reference single pass is the same whatever the loop's binarisation: one capture of the
    scheme's patterns plus white and black, thresholds ``(white + black) / 2``, every pixel with
    ``white - black > DEFAULT_MIN_CONTRAST`` reported, no check -- nearest codeword of the first
    code for EDC schemes (`edge.decode.decode(method="hard")`), the ensemble's majority column
    (ties: first code) for ensembles.  It is what a conventional sensor reports.
    """
    from edge.sim import capture

    from .adaptive import AdaptiveScan

    gen = np.random.default_rng(rng)
    result = run_adaptive(scene, camera, scheme, rng=gen, max_rounds=max_rounds, binarisation=binarisation,
                          **options)
    # single pass: same scheme, fresh noise, no check
    scan = AdaptiveScan(scheme, int(scene.geometry.projector_width), scene.height, full_scale=float(camera.levels),
                        binarisation="calibrated")
    frames = scan.start()
    cap = capture(scene, frames, camera, rng=gen, exposure=camera.frame_exposure(scan.scheme.n_frames))
    single = single_pass_columns(scan.scheme, cap, camera, DEFAULT_MIN_CONTRAST)
    truth = truth_columns(scene)
    single_valid = single >= 0
    single_wrong = single_valid & (single != truth)
    single_correct = single_valid & (single == truth)
    left = result.valid & (result.column != truth)
    n_single = int(single_wrong.sum())
    score = LoopScore(
        scheme=scan.scheme.name, binarisation=binarisation, rounds=result.n_rounds, frames=result.frames_per_round,
        frames_total=result.frames_total, calibration_frames=sum(r.calibration_frames for r in result.rounds),
        stop_reason=result.stop_reason, single_errors=n_single, errors_left=int(left.sum()),
        errors_left_unreached=int((left & (truth < 0)).sum()),
        removed=1.0 - float(left.sum()) / n_single if n_single else 1.0,
        correct_single=int(single_correct.sum()),
        wrongly_invalidated=float((single_correct & ~result.valid).sum() / max(1, single_correct.sum())),
        valid_fraction=float(result.valid[scene.lit].mean()) if scene.lit.any() else 0.0,
    )
    return score, result


def single_pass_columns(scheme: Any, captured: np.ndarray, camera: Any, min_contrast: float) -> np.ndarray:
    """(H, W) int32 columns of one unchecked pass (round-1 frames: patterns, white, black); -1 in shadow."""
    from edge.decode import decode

    n = scheme.n_frames
    white, black = captured[n], captured[n + 1]
    shadow = (white.astype(np.float32) - black.astype(np.float32)) / float(camera.levels) <= min_contrast
    cols = []
    start = 0
    for c in scheme.codes:
        dec = decode(captured[start:start + c.n], white, black, c, method="hard", min_contrast=0.0, min_confidence=0.0)
        cols.append(np.asarray(dec.candidates[..., 0]))
        start += c.n
    if len(cols) == 1:
        col = cols[0]
    else:
        stack = np.stack(cols).reshape(len(cols), -1)
        votes = (stack[:, None, :] == stack[None, :, :]).sum(axis=1)
        col = stack[votes.argmax(axis=0), np.arange(stack.shape[1])].reshape(cols[0].shape)
    return np.where(shadow, -1, col).astype(np.int32)

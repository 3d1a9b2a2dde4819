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

#: GI scenes of the evaluation (see docs/results/edc/README.md).  Each entry: scene parameters of
#: `edge.sim.make_scene`, plus ``base`` (the scene generator, default: the label up to a '-<digits>'
#: suffix) and ``camera`` (`CameraModel` overrides: a lower projector level where strong indirect
#: light would otherwise saturate the 8-bit camera, projector defocus).  Interreflection strength
#: 1/(1 - albedo * F) sums the higher bounces of the one-bounce model (F: face-to-face form factor).
#: The first four are the original scenes (a single pass barely errs on lit pixels there); the
#: others are calibrated so that a single pass of xor02-10+crc5 or gray-10+crc5 errs on 1-20 % of
#: the LIT pixels (camera 256 x 192, seed 0).
GI_SCENES: dict[str, dict[str, Any]] = {
    "v-groove": {"angle_deg": 40.0, "albedo": 0.9, "interreflection": 2.5},
    "v-groove-30": {"angle_deg": 30.0, "albedo": 0.9, "interreflection": 3.0},
    "bowl": {"radius": 0.3, "albedo": 0.9, "interreflection": 6.0},
    "scattering": {"scattering": 0.8},
    # concave corners, two bounces, strong inter-reflection (long range)
    "corner-30-2b": {"base": "v-groove", "angle_deg": 30.0, "albedo": 0.9, "interreflection": 4.0, "bounces": 2,
                     "camera": {"projector": 0.1}},
    "corner-45-2b": {"base": "v-groove", "angle_deg": 45.0, "albedo": 0.9, "interreflection": 4.0, "bounces": 2,
                     "camera": {"projector": 0.1}},
    # specular-ish (Phong lobe, exponent 30) corners and bowl, 4-pixel transport patches
    "corner-60-gloss": {"base": "v-groove", "angle_deg": 60.0, "albedo": 0.9, "interreflection": 3.0, "gloss": 30.0,
                        "gi_patch": 4, "camera": {"projector": 0.15}},
    "corner-90-gloss": {"base": "v-groove", "angle_deg": 90.0, "albedo": 0.9, "interreflection": 2.0, "gloss": 30.0,
                        "gi_patch": 4, "camera": {"projector": 0.2}},
    "bowl-gloss": {"base": "bowl", "radius": 0.3, "albedo": 0.9, "interreflection": 10.0, "gloss": 30.0,
                   "gi_patch": 4, "camera": {"projector": 0.1}},
    # sub-surface scattering at three kernel widths (short range)
    "scatter-s1.5": {"base": "scattering", "scattering": 0.9, "scattering_sigma": 1.5},
    "scatter-s4": {"base": "scattering", "scattering": 0.9, "scattering_sigma": 4.0},
    "scatter-s10": {"base": "scattering", "scattering": 0.9, "scattering_sigma": 10.0},
    # projector defocus (Gaussian blur in projector pixels) on a tilted plane
    "defocus-0.8": {"base": "tilted-plane", "camera": {"defocus_sigma": 0.8}},
    "defocus-0.9": {"base": "tilted-plane", "camera": {"defocus_sigma": 0.9}},
}


def _entry(label: str) -> dict[str, Any]:
    if label not in GI_SCENES:
        raise ValueError(f"unknown GI scene {label!r}; valid: {', '.join(GI_SCENES)}")
    return GI_SCENES[label]


def make_gi_scene(label: str, width: int, height: int, seed: int = 0):
    """Scene ``label`` of `GI_SCENES` (its ``base`` generator, default the label before a '-<digits>' suffix)."""
    from edge.sim import make_scene

    entry = _entry(label)
    base = entry.get("base", "v-groove" if label.startswith("v-groove") else label)
    params = {k: v for k, v in entry.items() if k not in ("base", "camera")}
    return make_scene(base, width, height, seed=seed, **params)


def gi_camera(label: str, camera: Any = None):
    """The `CameraModel` of scene ``label``: ``camera`` (default `CameraModel()`) with its overrides."""
    from edge.sim import CameraModel

    cam = camera if camera is not None else CameraModel()
    overrides = _entry(label).get("camera") or {}
    return cam.with_(**overrides) if overrides else cam


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


def per_bit_contrast(frames: np.ndarray, white: np.ndarray, black: np.ndarray, full_scale: float) -> np.ndarray:
    """(H, W) float32: the weakest bit's margin ``min_i |frame_i - (white + black) / 2| / full_scale``.

    The per-bit contrast map the paper describes (with inverse frames it would be
    ``min_i |frame_i - inverse_i|``): a pixel whose weakest bit sits close to its threshold is the
    one noise or indirect light flips.  Flag a pixel when this is below a threshold.
    """
    mid = (np.asarray(white, dtype=np.float32) + np.asarray(black, dtype=np.float32)) * np.float32(0.5)
    margin = np.min(np.abs(np.asarray(frames, dtype=np.float32) - mid[None]), axis=0)
    return (margin / np.float32(full_scale)).astype(np.float32)


def matched_caught(sweep: list[MapScore], false_reject: float) -> float:
    """Caught fraction of a threshold sweep at the largest threshold whose false-reject rate is <= ``false_reject``.

    The operating point is picked with the ground truth (an oracle choice), so the baseline is
    shown at its best for the CRC map's false-reject rate.
    """
    ok = [m.caught for m in sweep if m.false_reject <= false_reject + 1e-12]
    return max(ok) if ok else 0.0


def error_map_roc(scene: Any, camera: Any, code: Code, *, rng: Any = 0,
                  thresholds: np.ndarray | None = None,
                  bit_thresholds: np.ndarray | None = None) -> dict[str, Any]:
    """Single pass of ``code``: the CRC map next to the per-bit contrast and white - black maps.

    Returns, on the LIT pixels (the projector reaches them; good = decoded correctly, wrong =
    decoded wrongly by the unchecked single pass, nearest codeword):
    "edc" (CRC map, parameter-free MapScore), "contrast" (white - black < t over ``thresholds``),
    "perbit" (weakest-bit margin < t over ``bit_thresholds``), "combined" (CRC OR white - black),
    "crc_perbit" (CRC OR per-bit), the threshold arrays, and "unlit": for the pixels the projector
    does NOT reach (every decode there is wrong; indirect light only) the fraction each map flags:
    {"pixels", "edc", "contrast@0.03", "perbit@t*", "crc_perbit@t*"} with t* the per-bit threshold
    matched to the CRC map's false-reject rate on lit pixels.
    """
    from edge.decode import check, contrast_error_map, decode
    from edge.sim import capture_code

    cap = capture_code(scene, code, camera, rng=rng)
    dec = decode(cap.frames, cap.white, cap.black, code, method="hard", min_contrast=0.0, min_confidence=0.0)
    col = np.asarray(dec.candidates[..., 0] if dec.candidates is not None else dec.column)
    truth = truth_columns(scene)
    lit = truth >= 0
    wrong = col != truth
    ts = np.linspace(0.0, 0.3, 31) if thresholds is None else np.asarray(thresholds, dtype=float)
    bts = (np.concatenate([np.linspace(0.0, 0.02, 41), np.linspace(0.025, 0.2, 36)]) if bit_thresholds is None
           else np.asarray(bit_thresholds, dtype=float))
    edc = check(cap.frames, cap.white, cap.black, code)
    pb = per_bit_contrast(cap.frames, cap.white, cap.black, float(camera.levels))
    contrast = [score_map(contrast_error_map(cap.white, cap.black, float(t)), wrong, lit) for t in ts]
    combined = [score_map(edc | contrast_error_map(cap.white, cap.black, float(t)), wrong, lit) for t in ts]
    perbit = [score_map(pb < t, wrong, lit) for t in bts]
    crc_perbit = [score_map(edc | (pb < t), wrong, lit) for t in bts]
    e = score_map(edc, wrong, lit)
    ok = [i for i, m in enumerate(perbit) if m.false_reject <= e.false_reject + 1e-12]
    t_star = float(bts[max(ok, key=lambda i: (perbit[i].caught, bts[i]))]) if ok else 0.0
    unlit = ~lit
    n_unlit = int(unlit.sum())

    def frac(flags: np.ndarray) -> float:
        return float((flags & unlit).sum() / max(1, n_unlit))

    return {
        "edc": e, "contrast": contrast, "combined": combined, "perbit": perbit, "crc_perbit": crc_perbit,
        "thresholds": ts, "bit_thresholds": bts, "t_star": t_star,
        "unlit": {"pixels": n_unlit, "edc": frac(edc), "contrast@0.03": frac(contrast_error_map(cap.white, cap.black, 0.03)),
                  "perbit@t*": frac(pb < t_star), "crc_perbit@t*": frac(edc | (pb < t_star))},
    }


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
    lit_pixels: int = 0                # pixels the projector reaches
    single_correct_lit: float = 0.0    # fraction of lit pixels the single pass decodes correctly
    single_wrong_lit: float = 0.0      # ... reports valid with a wrong column
    single_wrong_unlit: int = 0        # unlit pixels the single pass reports (all wrong)
    correct_lit: float = 0.0           # after the loop
    wrong_lit: float = 0.0
    wrong_unlit: int = 0
    conventional_correct_lit: float = 0.0  # the white/black single pass (17 frames), for reference


def score_loop(scene: Any, camera: Any, scheme: Any, *, rng: Any = 0, max_rounds: int = 3,
               binarisation: str = "self", **options: Any) -> tuple[LoopScore, AdaptiveResult]:
    """Run the adaptive loop of ``scheme`` and compare with the reference single pass of the SAME scheme.

    The reference single pass uses the loop's binarisation (self: the n pattern frames, each pixel
    thresholded at its own (max + min) / 2; calibrated: patterns + white + black), every pixel over
    the floor reported with its nearest codeword (ensembles: the majority column), no check -- the
    loop's own round 1 without the check, on fresh noise.  ``conventional_correct_lit`` is the
    white/black single pass (what a conventional sensor reports) for reference.
    """
    from edge.sim import capture

    from .adaptive import AdaptiveScan

    gen = np.random.default_rng(rng)
    result = run_adaptive(scene, camera, scheme, rng=gen, max_rounds=max_rounds, binarisation=binarisation,
                          **options)
    # single pass with the SAME binarisation: one round, fresh noise, every pixel's guess, no check
    scan = AdaptiveScan(scheme, int(scene.geometry.projector_width), scene.height, full_scale=float(camera.levels),
                        binarisation=binarisation, max_rounds=1,
                        noise=options.get("noise", (float(camera.sigma_r), float(camera.sigma_s))))
    frames = scan.start()
    scan.update(capture(scene, frames, camera, rng=gen, exposure=camera.frame_exposure(scan.scheme.n_frames)))
    single = scan.guesses
    # the conventional single pass (white + black, threshold (white + black) / 2), for reference
    conv = AdaptiveScan(scheme, int(scene.geometry.projector_width), scene.height, full_scale=float(camera.levels),
                        binarisation="calibrated")
    cap = capture(scene, conv.start(), camera, rng=gen, exposure=camera.frame_exposure(conv.scheme.n_frames))
    conventional = single_pass_columns(conv.scheme, cap, camera, DEFAULT_MIN_CONTRAST)
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
        **lit_unlit(single, result.column, truth),
        conventional_correct_lit=lit_unlit(conventional, conventional, truth)["correct_lit"],
    )
    return score, result


def lit_unlit(single: np.ndarray, column: np.ndarray, truth: np.ndarray) -> dict[str, Any]:
    """Correct / wrong fractions of the LIT pixels and wrong counts of the unlit ones, single pass vs loop."""
    lit = truth >= 0
    n = max(1, int(lit.sum()))

    def part(col: np.ndarray) -> tuple[float, float, int]:
        valid = col >= 0
        return (float((valid & (col == truth) & lit).sum() / n), float((valid & (col != truth) & lit).sum() / n),
                int((valid & ~lit).sum()))

    sc, sw, su = part(single)
    lc, lw, lu = part(column)
    return {"lit_pixels": int(lit.sum()), "single_correct_lit": sc, "single_wrong_lit": sw, "single_wrong_unlit": su,
            "correct_lit": lc, "wrong_lit": lw, "wrong_unlit": lu}


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

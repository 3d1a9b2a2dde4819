"""Tests for edge.edc: the CRC error map, the adaptive loop, the Gupta baseline."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from edge.codes import get_code
from edge.edc.adaptive import AdaptiveScan, run_adaptive, supported
from edge.edc.gupta import EnsembleScheme, ensemble_vote
from edge.edc.lookup import lookup_columns
from edge.edc.maxminsw import maxminsw_code, stripe_widths, verify_walk
from edge.edc.scheme import EdcScheme, unmeasurable_columns

EDC = "xor02-10+crc5"


def _synthetic(words: np.ndarray, lo: float = 10.0, hi: float = 200.0):
    """Frames (n, P) from 0/1 words (P, n), with white/black (P,)."""
    frames = (lo + (hi - lo) * words.T).astype(np.float32)
    p = words.shape[0]
    return frames, np.full(p, hi, np.float32), np.full(p, lo, np.float32)


def _flip_all(code, patterns):
    cb = code.codebook.astype(np.uint8)
    words = (cb[:, None, :] ^ patterns[None, :, :]).reshape(-1, code.n)
    return words


def test_crc_map_flags_every_pattern_below_dmin():
    from edge.decode import check

    code = get_code(EDC)
    assert code.d_min == 4
    pats = []
    for w in range(1, code.d_min):
        for pos in itertools.combinations(range(code.n), w):
            e = np.zeros(code.n, np.uint8)
            e[list(pos)] = 1
            pats.append(e)
    words = _flip_all(code, np.array(pats))  # 1024 columns x 575 patterns
    frames, white, black = _synthetic(words)
    assert (lookup_columns(frames, white, black, code) < 0).all()
    # the decoder helper's parameter-free check agrees
    assert check(frames[:, None, :], white[None], black[None], code).all()
    # and at weight d_min some patterns do land on codewords (the bound is tight)
    e4 = np.zeros((1, code.n), np.uint8)
    diff = code.codebook[0] ^ code.codebook[1:]
    e4[0] = diff[(diff.sum(axis=1) == code.d_min).argmax()]
    f4, w4, b4 = _synthetic(_flip_all(code, e4))
    assert (lookup_columns(f4, w4, b4, code) >= 0).all()


@pytest.mark.parametrize("name", [EDC, "gray-10+crc5"])
def test_crc_map_flags_every_burst_up_to_crc_width(name):
    code = get_code(name)
    r = code.n - code.k
    pats = []
    for length in range(1, r + 1):
        for start in range(code.n - length + 1):
            inner = [np.array(m, np.uint8) for m in itertools.product((0, 1), repeat=max(0, length - 2))]
            for mid in inner:
                e = np.zeros(code.n, np.uint8)
                e[start] = 1
                e[start + length - 1] = 1
                if length > 2:
                    e[start + 1:start + length - 1] = mid
                pats.append(e)
    words = _flip_all(code, np.unique(np.array(pats), axis=0))
    frames, white, black = _synthetic(words)
    assert (lookup_columns(frames, white, black, code) < 0).all()


def test_lookup_decodes_clean_codewords_and_matches_check():
    from edge.decode import check

    code = get_code(EDC)
    rng = np.random.default_rng(0)
    frames, white, black = _synthetic(code.codebook.astype(np.uint8))
    assert np.array_equal(lookup_columns(frames, white, black, code), np.arange(code.size))
    noisy = frames + rng.normal(0, 60, frames.shape).astype(np.float32)
    mine = lookup_columns(noisy, white, black, code) < 0
    theirs = check(np.clip(noisy, 0, None)[:, None, :], white[None], black[None], code)[0]
    assert mine.any() and np.array_equal(mine, theirs)


def _sim():
    from edge.sim import CameraModel, make_scene

    return make_scene, CameraModel


def test_masked_patterns_remove_indirect_light():
    make_scene, CameraModel = _sim()
    from edge.sim import capture

    scene = make_scene("v-groove", 96, 48, seed=0, angle_deg=40.0, albedo=0.9, interreflection=2.5, texture=0.0)
    cam = CameraModel(sigma_r=0.0, sigma_s=0.0, bits=16, ambient=0.0, projector=0.2)
    wp = int(scene.geometry.projector_width)
    cols = scene.column_int
    left = cols[:, : scene.width // 2]
    c_split = int(left[left >= 0].max())
    all_on = np.full((1, scene.height, wp), 255, np.uint8)
    half = all_on.copy()
    half[:, :, c_split + 1:] = 0  # switch off the columns of the right face
    a = capture(scene, all_on, cam, rng=0)[0].astype(float)
    b = capture(scene, half, cam, rng=0)[0].astype(float)
    lit_left = (cols >= 0) & (cols <= c_split - 3)
    near_hinge = lit_left & (np.abs(np.arange(scene.width) - scene.width // 2) < 10)[None, :]
    # left-face pixels keep their direct light but lose the light the right face reflected onto them
    assert (b[near_hinge] < a[near_hinge] * 0.95).all()
    # right-face pixels lose their direct light; what is left is the left face's reflection
    dark = cols > c_split + 3
    assert (b[dark] < 0.75 * a[dark]).all() and (b[dark] > 0).all()


def test_adaptive_round2_frames_are_masked_and_counted_calibrated():
    make_scene, CameraModel = _sim()
    from edge.sim import capture

    scene = make_scene("v-groove", 96, 48, seed=0, angle_deg=30.0, albedo=0.9, interreflection=3.0)
    cam = CameraModel()
    code = get_code(EDC)
    scan = AdaptiveScan(code, int(scene.geometry.projector_width), scene.height, full_scale=cam.levels,
                        binarisation="calibrated")
    frames = scan.start()
    assert frames.shape == (code.n + 2, scene.height, scene.geometry.projector_width)
    assert (frames[code.n] == 255).all() and (frames[code.n + 1] == 0).all()
    t = cam.frame_exposure(code.n)
    r1 = scan.update(capture(scene, frames, cam, rng=1, exposure=t))
    assert r1.frames == 17 and r1.calibration_frames == 2 and r1.resolved > 0
    nxt = scan.next_frames()
    assert nxt is not None and nxt.shape[0] == code.n + 1
    res = scan.result()
    y, x = np.argwhere(res.valid)[0]
    # the column a passing pixel claimed is dark in every frame of round 2 (unless guarded)
    guarded = (~res.valid[y, max(0, x - 1):x + 2]).any()
    if not guarded:
        assert (nxt[:, y, res.column[y, x]] == 0).all()
    assert (nxt[code.n] > 0).mean() < 1.0  # round 2 lights fewer projector pixels
    r2 = scan.update(capture(scene, nxt, cam, rng=2, exposure=t))
    assert r2.checked == r1.failing and r2.calibration_frames == 1


def test_self_calibrated_rounds_have_no_calibration_frames():
    make_scene, CameraModel = _sim()
    from edge.sim import capture

    scene = make_scene("v-groove", 96, 48, seed=0, angle_deg=30.0, albedo=0.9, interreflection=3.0)
    cam = CameraModel()
    code = get_code(EDC)
    scan = AdaptiveScan(code, int(scene.geometry.projector_width), scene.height, full_scale=cam.levels,
                        noise=(cam.sigma_r, cam.sigma_s))
    assert scan.binarisation == "self"  # the default
    frames = scan.start()
    assert frames.shape[0] == code.n == scan.expected_frames
    t = cam.frame_exposure(code.n)
    r1 = scan.update(capture(scene, frames, cam, rng=1, exposure=t))
    assert r1.frames == code.n and r1.calibration_frames == 0 and r1.resolved > 0
    res = scan.result()
    assert not (res.column == 0).any()  # column 0 (all-zero codeword) is never claimed
    nxt = scan.next_frames()
    assert nxt is not None and nxt.shape[0] == code.n and (nxt > 0).mean() < (frames > 0).mean()
    r2 = scan.update(capture(scene, nxt, cam, rng=2, exposure=t))
    assert r2.checked == r1.failing and r2.frames == code.n


def test_self_binarisation_matches_calibrated_on_clean_words():
    code = get_code(EDC)
    words = code.codebook.astype(np.uint8)
    frames, white, black = _synthetic(words)
    scheme = EdcScheme(code)
    col_cal, _ = scheme.decide(frames, white, black)
    col_self, _ = scheme.decide(frames, frames.max(axis=0), frames.min(axis=0))
    # identical except column 0, whose all-zero word has no 1 to calibrate on
    assert np.array_equal(col_cal, np.arange(code.size))
    assert np.array_equal(col_self[1:], np.arange(1, code.size))
    assert unmeasurable_columns(scheme).nonzero()[0].tolist() == [0]
    assert unmeasurable_columns(EdcScheme("gray-10+crc5")).nonzero()[0].tolist() == [0]
    # CRC 0x15 has the factor x+1: every codeword has even weight, so none is all-one (n = 15 odd)
    assert (code.codebook.sum(axis=1) % 2 == 0).all()


def test_neighbour_support_rule():
    col = np.full((5, 7), -1, np.int64)
    col[2, 1:6] = [100, 101, 900, 103, 104]    # 900: a chance codeword amid a smooth surface
    col[0:5, 0] = -1
    cand = col >= 0
    ok = supported(col, cand, 3)
    assert ok[2, 1] and ok[2, 2] and ok[2, 4] and ok[2, 5] and not ok[2, 3]
    # a one-pixel-wide lit strip: no horizontal neighbour decoded, vertical agreement counts
    strip = np.full((4, 5), -1, np.int64)
    strip[:, 2] = [50, 50, 51, 52]
    assert supported(strip, strip >= 0, 3)[:, 2].all()
    # a vertical run of one wrong column next to decoded, different columns: rejected
    edge = np.tile(np.array([200, 201, 7, 203], np.int64), (4, 1))
    assert not supported(edge, edge >= 0, 3)[:, 2].any()
    # an isolated pixel has no support
    lone = np.full((3, 3), -1, np.int64)
    lone[1, 1] = 10
    assert not supported(lone, lone >= 0, 3).any()


def test_loop_terminates_when_nothing_can_be_resolved():
    make_scene, CameraModel = _sim()
    scene = make_scene("v-groove", 64, 32, seed=0)
    dark = CameraModel(projector=0.0)  # no projector light reaches anything
    res = run_adaptive(scene, dark, EDC, rng=0, max_rounds=5)
    # self-calibrated: a few noise pixels may clear the 6-sigma floor, fail the check, and end it as "no change"
    assert res.n_rounds == 1 and not res.valid.any() and res.stop_reason in ("nothing to resolve", "no change")
    res = run_adaptive(scene, dark, EDC, rng=0, max_rounds=5, binarisation="calibrated")
    assert res.n_rounds == 1 and not res.valid.any() and res.stop_reason == "nothing to resolve"


@pytest.mark.parametrize("mode", ["self", "calibrated"])
def test_loop_terminates_on_garbage_frames(mode):
    code = get_code(EDC)
    rng = np.random.default_rng(0)
    scan = AdaptiveScan(code, 1024, 16, max_rounds=4, binarisation=mode, neighbour_tolerance=None)
    frames = scan.start()
    rounds = 0
    while frames is not None:
        cap = rng.integers(0, 251, size=(frames.shape[0], 16, 40)).astype(np.uint8)
        if mode == "calibrated":
            cap[code.n] = 250  # bright white: every pixel over the shadow floor, words random
            if rounds == 0:
                cap[code.n + 1] = 0
        scan.update(cap)
        rounds += 1
        frames = scan.next_frames()
        assert rounds <= 4
    res = scan.result()
    assert res.n_rounds == rounds <= 4 and res.stop_reason in ("no change", "round limit", "nothing to light")


def test_bad_inputs():
    code = get_code(EDC)
    with pytest.raises(ValueError, match="round limit"):
        AdaptiveScan(code, 1024, 8, max_rounds=0)
    with pytest.raises(ValueError, match="binarisation"):
        AdaptiveScan(code, 1024, 8, binarisation="otsu")
    with pytest.raises(ValueError, match="neighbour_tolerance"):
        AdaptiveScan(code, 1024, 8, neighbour_tolerance=-1)
    selfcal = AdaptiveScan(code, 1024, 8)
    selfcal.start()
    with pytest.raises(ValueError, match="expects 15 frames"):
        selfcal.update(np.zeros((17, 8, 10), np.uint8))  # calibrated-mode frame count
    scan = AdaptiveScan(code, 1024, 8, binarisation="calibrated")
    with pytest.raises(ValueError, match="start"):
        scan.update(np.zeros((17, 8, 10), np.uint8))
    scan.start()
    with pytest.raises(ValueError, match="update"):
        scan.next_frames()
    with pytest.raises(ValueError, match="expects 17 frames"):
        scan.update(np.zeros((12, 8, 10), np.uint8))  # frames of a 10-frame code
    with pytest.raises(ValueError, match="cannot continue"):
        scan.update(np.zeros((17, 8, 10), np.uint8), code="gray-10+crc5")
    cap = np.zeros((17, 8, 10), np.uint8)
    cap[15] = 200
    cap[:5] = 200
    scan.update(cap)
    if not scan.done:
        with pytest.raises(ValueError, match="like round 1"):
            scan.update(np.zeros((16, 8, 12), np.uint8))
    with pytest.raises(ValueError):
        AdaptiveScan("no-such-code", 1024, 8)


@pytest.mark.parametrize("label", ["v-groove-30", "scattering"])
def test_targets_on_small_gi_scene(label):
    from edge.edc.evaluate import make_gi_scene, score_loop

    _, CameraModel = _sim()
    scene = make_gi_scene(label, 128, 64, seed=0)
    score, result = score_loop(scene, CameraModel(), EDC, rng=0)  # default: self-calibrated
    assert score.single_errors > 50  # the scene really has errors to remove
    assert score.rounds <= 3 and score.calibration_frames == 0
    assert score.frames_total <= 45
    assert score.removed >= 0.8
    assert score.wrongly_invalidated < 0.01


def test_neighbour_support_removes_unreached_false_passes():
    from edge.edc.evaluate import make_gi_scene, score_loop

    _, CameraModel = _sim()
    scene = make_gi_scene("v-groove-30", 128, 64, seed=0)
    before, _ = score_loop(scene, CameraModel(), EDC, rng=0, neighbour_tolerance=None)
    after, _ = score_loop(scene, CameraModel(), EDC, rng=0)
    assert before.errors_left_unreached > 0
    assert after.errors_left_unreached <= before.errors_left_unreached // 2
    assert after.wrongly_invalidated < 0.01


def test_ensemble_vote():
    cols = np.array([[5, 1, 7, 3, -1], [5, 2, 7, 4, -1], [9, 3, 8, 3, 6], [9, 4, 8, 4, -1]])
    col, ok = ensemble_vote(cols)
    assert ok.tolist() == [False, False, False, False, False]  # 2-2 splits and no agreement
    cols = np.array([[5, 1, 7], [5, 2, 7], [9, 1, 7], [8, 4, 2]])
    col, ok = ensemble_vote(cols)
    assert col.tolist() == [5, 1, 7] and ok.all()


def test_maxminsw_is_a_gray_code_with_wide_stripes():
    from edge.edc.maxminsw import cyclic_gray_walk, cyclic_min_gap

    code = maxminsw_code(10)
    assert code.family == "maxminsw" and code.size == 1024
    # every column's word is unique, neighbours differ in one bit, also across the wrap-around
    assert np.unique(code.messages).size == 1024
    assert (np.bitwise_count((code.messages[1:] ^ code.messages[:-1]).astype(np.uint64)) == 1).all()
    assert cyclic_min_gap(code.messages, 10) == 7
    assert verify_walk(code.messages, 10) >= 7
    assert stripe_widths(code).min() >= 7 > 2 == stripe_widths(get_code("xor04-10")).min()
    assert stripe_widths(get_code("gray-10")).min() == 2
    assert (code.neighbour_distances() == 1).all()
    # the 5-bit building block: min gap 4 exists, 5 does not (exhaustive)
    assert cyclic_min_gap(cyclic_gray_walk(5, 4), 5) == 4 and cyclic_gray_walk(5, 5) is None
    with pytest.raises(ValueError, match="reaches min run 7"):
        maxminsw_code(10, 8)
    with pytest.raises(ValueError, match="one bit"):
        cyclic_min_gap(np.arange(1024), 10)


def test_gupta_scheme_frames():
    scheme = EnsembleScheme()
    assert scheme.n_frames == 40
    assert [c.name for c in scheme.codes] == ["gray-10", "maxminsw-10", "xor04-10", "xor02-10"]
    words = np.concatenate([c.codebook for c in scheme.codes], axis=1)[:300]
    frames, white, black = _synthetic(words)
    col, ok = scheme.decide(frames, white, black)
    assert ok.all() and np.array_equal(col, np.arange(300))

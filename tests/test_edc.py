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


def test_adaptive_full_scale_default_detects_12_bit_data_in_uint16():
    # without full_scale, 12-bit data in uint16 was read at 65535 (16x darker than it is), and the
    # calibrated contrast floor (a fraction of full scale) took a different set of pixels
    make_scene, CameraModel = _sim()
    from edge.sim import capture

    scene = make_scene("v-groove", 96, 48, seed=0, angle_deg=30.0, albedo=0.9)
    cam = CameraModel(bits=12)
    assert cam.levels == 4095
    results = []
    for fs in (cam.levels, None):
        scan = AdaptiveScan(EDC, int(scene.geometry.projector_width), scene.height, full_scale=fs,
                            binarisation="calibrated", min_contrast=0.05)
        frames = scan.start()
        shot = capture(scene, frames, cam, rng=1, exposure=cam.frame_exposure(frames.shape[0] - 2))
        assert shot.dtype == np.uint16 and shot.max() <= 4095
        scan.update(shot)
        assert scan.full_scale == 4095.0
        results.append(scan.result())
    assert results[0].valid.any()
    assert np.array_equal(results[0].valid, results[1].valid)
    assert np.array_equal(results[0].column, results[1].column)


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
    cap[:15] = 200 * code.codebook[np.arange(10)].T[:, None, :]  # rows 0-3: codewords of columns 0..9
    cap[:15, 4:] = 200 * np.random.default_rng(0).integers(0, 2, (15, 4, 10), dtype=np.uint8)  # rows 4-7: CRC fails
    first = scan.update(cap)
    assert (first.resolved, first.failing) == (40, 40) and not scan.done, "rows 4-7 are left for round 2"
    with pytest.raises(ValueError, match="like round 1"):
        scan.update(np.zeros((16, 8, 12), np.uint8))
    with pytest.raises(ValueError):
        AdaptiveScan("no-such-code", 1024, 8)


@pytest.mark.parametrize("label", ["v-groove-30", "scattering"])
def test_targets_on_small_gi_scene(label):
    from edge.eval.edc import make_gi_scene, score_loop

    _, CameraModel = _sim()
    scene = make_gi_scene(label, 128, 64, seed=0)
    score, result = score_loop(scene, CameraModel(), EDC, rng=0)  # default: self-calibrated
    assert score.single_errors > 50  # the scene really has errors to remove
    assert score.rounds <= 3 and score.calibration_frames == 0
    assert score.frames_total <= 45
    assert score.removed >= 0.8
    assert score.wrongly_invalidated < 0.01


def test_neighbour_support_removes_unreached_false_passes():
    from edge.eval.edc import make_gi_scene, score_loop

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


# ---------------------------------------------------------------------------------------------
# sparse kernels, the never-worse loop, scenes that break codes on lit pixels, the runtime stage


def test_sparse_kernels_match_numpy_references():
    from edge.edc import _kernels as K
    from edge.edc.lookup import pack_bits, packed_codewords

    rng = np.random.default_rng(3)
    code = get_code(EDC)
    frames = rng.integers(0, 256, size=(code.n + 2, 20, 30)).astype(np.uint8)
    white, black = frames[code.n], frames[code.n + 1]
    mask = rng.random((20, 30)) < 0.6
    ys, xs = np.nonzero(mask)
    hi, lo = K.gather_pixels(white, ys, xs), K.gather_pixels(black, ys, xs)
    ref = pack_bits(frames[:code.n], (white.astype(np.float32) + black.astype(np.float32)) / 2)
    assert np.array_equal(K.pack_words_at(frames, 0, code.n, ys, xs, hi, lo), ref[ys, xs])
    assert np.array_equal(K.pack_words_full(frames, 0, code.n, white, black), ref)
    h2, l2 = K.extremes_full(frames, code.n)
    assert np.array_equal(h2, frames[:code.n].max(axis=0)) and np.array_equal(l2, frames[:code.n].min(axis=0))
    hs, ls = K.gather_extremes(frames, ys, xs, code.n)
    assert np.array_equal(hs, h2[ys, xs]) and np.array_equal(ls, l2[ys, xs])
    words = ref[ys, xs]
    book = packed_codewords(code)
    dist = np.bitwise_count((words[:, None] ^ book[None, :]).astype(np.uint64))
    assert np.array_equal(K.nearest_codewords(words, book), dist.argmin(axis=1))
    col = np.where(rng.random((20, 30)) < 0.7, rng.integers(0, 12, size=(20, 30)), -1)
    cand = col >= 0
    cy, cx = np.nonzero(cand)
    assert np.array_equal(K.support_at(cy, cx, col[cy, cx].astype(np.int32), col.astype(np.int32), 3),
                          supported(col, cand, 3)[cy, cx])


def test_region_growing_keeps_smooth_guesses_only():
    from edge.edc import _kernels as K

    verified = np.full((3, 8), -1, np.int32)
    verified[:, 0] = [100, 100, 100]
    guess = np.tile(np.array([100, 101, 102, 103, 600, 601, 602, 603], np.int32), (3, 1))
    cy, cx = np.nonzero(verified < 0)
    out = K.grow_guesses(verified, guess, cy, cx, 3)
    # the smooth run next to the verified column is kept; the jump (a wrong word) and what lies beyond it is not
    assert (out[:, :4] == guess[:, :4]).all() and (out[:, 4:] == -1).all()


@pytest.mark.parametrize("code", [EDC, "gray-10+crc5"])
def test_loop_never_lowers_correct_fraction_on_any_gi_scene(code):
    from edge.eval.edc import GI_SCENES, gi_camera, make_gi_scene, score_loop

    for label in GI_SCENES:
        scene = make_gi_scene(label, 96, 64, seed=0)
        score, result = score_loop(scene, gi_camera(label), code, rng=0)
        assert score.correct_lit >= score.single_correct_lit, (label, score)
        assert score.frames_total <= 45


def test_later_rounds_never_change_or_invalidate_a_reported_pixel():
    from edge.eval.edc import gi_camera, make_gi_scene
    from edge.sim.metrics import truth_columns
    from edge.sim import capture

    label = "corner-30-2b"
    scene, cam = make_gi_scene(label, 96, 64, seed=0), gi_camera(label)
    truth = truth_columns(scene)
    scan = AdaptiveScan("gray-10+crc5", int(scene.geometry.projector_width), scene.height, full_scale=cam.levels,
                        noise=(cam.sigma_r, cam.sigma_s))
    frames, gen, before, correct = scan.start(), np.random.default_rng(1), None, []
    while frames is not None:
        scan.update(capture(scene, frames, cam, rng=gen, exposure=cam.frame_exposure(15)))
        res = scan.result()
        if before is not None:
            # verified pixels keep their column; nothing reported before becomes invalid
            assert np.array_equal(res.column[before.verified], before.column[before.verified])
            assert res.valid[before.valid].all()
        correct.append(int(((res.column == truth) & (truth >= 0)).sum()))
        before = res
        frames = scan.next_frames()
    assert len(correct) >= 2 and correct == sorted(correct)


@pytest.mark.parametrize("label", ["corner-30-2b", "defocus-0.8"])
def test_broken_scene_is_brought_under_half_a_percent_wrong_in_45_frames(label):
    from edge.eval.edc import gi_camera, make_gi_scene, score_loop

    scene = make_gi_scene(label, 96, 64, seed=0)
    score, _ = score_loop(scene, gi_camera(label), EDC, rng=0)
    assert score.single_wrong_lit >= 0.05  # a single pass really errs on lit pixels here
    assert score.conventional_correct_lit < 0.95  # ... also with white / black frames
    assert score.frames_total <= 45 and score.calibration_frames == 0
    assert score.wrong_lit <= 0.005
    assert score.correct_lit >= score.single_correct_lit


def test_gray_crc_on_the_30_degree_groove_ends_at_or_above_the_single_pass():
    from edge.eval.edc import gi_camera, make_gi_scene, score_loop

    scene = make_gi_scene("v-groove-30", 128, 96, seed=0)
    score, _ = score_loop(scene, gi_camera("v-groove-30"), "gray-10+crc5", rng=0)
    assert score.single_wrong_lit > 0.01
    assert score.correct_lit >= max(score.single_correct_lit, score.conventional_correct_lit)
    assert score.wrong_lit == 0.0


def test_reproject_all_baseline_projects_everything_every_round():
    make_scene, CameraModel = _sim()
    from edge.sim import capture

    scene = make_scene("v-groove", 64, 32, seed=0, angle_deg=30.0, albedo=0.9, interreflection=3.0)
    cam = CameraModel()
    scan = AdaptiveScan(EDC, int(scene.geometry.projector_width), scene.height, full_scale=cam.levels,
                        masking=False, max_rounds=3)
    frames, rounds = scan.start(), 0
    first = frames.copy()
    while frames is not None:
        assert np.array_equal(frames, first)
        scan.update(capture(scene, frames, cam, rng=rounds, exposure=cam.frame_exposure(15)))
        rounds += 1
        frames = scan.next_frames()
    assert rounds == 3 or scan.result().stop_reason == "all resolved"


def test_gi_scene_parameters_and_per_bit_contrast():
    from edge.eval.edc import gi_camera, make_gi_scene, per_bit_contrast
    from edge.sim import CameraModel, make_scene

    assert gi_camera("defocus-0.8").defocus_sigma == 0.8 and gi_camera("v-groove") == CameraModel()
    with pytest.raises(ValueError, match="unknown GI scene"):
        make_gi_scene("no-such-scene", 32, 16)
    with pytest.raises(ValueError, match="bounces"):
        make_scene("v-groove", 32, 16, bounces=0)
    with pytest.raises(ValueError, match="gloss"):
        make_scene("v-groove", 32, 16, gloss=-1.0)
    one = make_scene("v-groove", 48, 32, interreflection=2.0, albedo=0.9)
    two = make_scene("v-groove", 48, 32, interreflection=2.0, albedo=0.9, bounces=2)
    glossy = make_scene("v-groove", 48, 32, interreflection=2.0, albedo=0.9, gloss=30.0, gi_patch=4)
    e = np.ones((1, 32, 48), np.float32) * one.lit[None]
    i1, i2 = (s.interreflection.indirect(e * s.albedo[None]) for s in (one, two))
    assert (i2 >= i1 - 1e-6).all() and i2.sum() > i1.sum()  # the second bounce adds light
    assert glossy.interreflection.form_factor.shape[0] == (32 // 4) * (48 // 4)
    frames = np.array([[[10, 200]], [[120, 90]]], np.uint8)
    white, black = np.array([[200, 200]], np.uint8), np.array([[10, 10]], np.uint8)
    assert np.allclose(per_bit_contrast(frames, white, black, 255.0), [[15 / 255, 15 / 255]])


def test_masked_rows_render_exactly_without_global_illumination():
    from edge.sim import CameraModel, capture, make_scene

    scene = make_scene("tilted-plane", 64, 32, seed=0)
    cam = CameraModel(sigma_r=0.0, sigma_s=0.0)
    frames = np.zeros((3, 32, int(scene.geometry.projector_width)), np.uint8)
    frames[:, 5:9] = 255
    rows = np.arange(4, 10)
    full = capture(scene, frames, cam, rng=0)
    assert np.array_equal(capture(scene, frames, cam, rng=0, rows=rows), full[:, rows])
    gi = make_scene("v-groove", 64, 32, seed=0)
    with pytest.raises(ValueError, match="global illumination"):
        capture(gi, frames, cam, rng=0, rows=rows)


def test_runtime_edc_stage_column_and_confidence_are_consistent():
    from tests._service_helpers import load_test_profile

    from edge.runtime.assembly import StackAssembler
    from edge.runtime.pipeline import DepthPipeline
    from edge.sensors.sim import SimSensor

    profile = load_test_profile(edc={"rounds": 3})
    pipe, soft = DepthPipeline(profile), DepthPipeline(load_test_profile())
    sensor = SimSensor(profile, stacks=1, max_speed=True)
    asm = StackAssembler(pipe.schedule)
    sensor.start()
    stack = None
    try:
        while stack is None:
            frame = sensor.read(5.0)
            stack = asm.push(frame) if frame is not None else None
        requested = []

        def masked(stack_id, edc_round, frames):
            requested.append(frames)
            return sensor.capture_masked(stack_id, edc_round, frames)

        r = pipe.process(stack, masked)
        s = soft.process(stack)
    finally:
        sensor.stop()
    assert r.edc_rounds >= 1 and len(r.edc_round_ms) == r.edc_rounds
    assert r.frames_per_depth_map == len(stack.frames) + len(r.extra_frames)
    valid = r.column >= 0
    assert ((r.confidence > 0) == valid).all() and ((r.depth_mm > 0) == valid).all()
    same = valid & (r.column == s.column)
    # where EDC publishes the soft decoder's column it publishes the soft decoder's confidence
    assert np.array_equal(r.confidence[same], s.confidence[same])
    assert (r.confidence[valid & ~same] == 255).all()  # a verified codeword the soft decoder did not give
    assert valid.sum() >= 0.99 * (s.column >= 0).sum()
    for frames in requested:  # only rows with an open pixel are lit in a masked round
        assert frames.shape[1] == profile.camera.height and (frames.any(axis=(0, 2)).mean() < 0.5)


def test_bench_service_sets_edc_rounds(tmp_path):
    from _tools import load_tool

    bench = load_tool("bench_service")
    path, profile = bench.edc_profile("sim-dlp", 3, tmp_path)
    assert path.exists() and profile.edc.rounds == 3 and profile.name == "sim-dlp"


@pytest.mark.parametrize("mode", ["self", "calibrated"])
def test_fast_round1_matches_the_generic_path(mode):
    from edge.eval.edc import gi_camera, make_gi_scene
    from edge.sim import capture

    scene, cam = make_gi_scene("scatter-s4", 96, 64, seed=0), gi_camera("scatter-s4")
    results = []
    for fast in (True, False):
        scan = AdaptiveScan(EDC, int(scene.geometry.projector_width), scene.height, full_scale=cam.levels,
                            binarisation=mode, noise=(cam.sigma_r, cam.sigma_s))
        scan.fast_round1 = fast
        gen = np.random.default_rng(4)
        frames = scan.start()
        while frames is not None:
            scan.update(capture(scene, frames, cam, rng=gen, exposure=cam.frame_exposure(15)))
            frames = scan.next_frames()
        results.append((scan.result(), scan.guesses))
    (a, ga), (b, gb) = results
    assert np.array_equal(a.column, b.column) and np.array_equal(a.round_of, b.round_of)
    assert np.array_equal(ga, gb) and [r.resolved for r in a.rounds] == [r.resolved for r in b.rounds]


def test_small_row_render_matches_the_kernels_with_noise():
    from edge.sim import CameraModel, capture, make_scene
    from edge.sim import render

    scene = make_scene("tilted-plane", 64, 32, seed=0)
    cam = CameraModel()
    frames = np.zeros((5, 32, int(scene.geometry.projector_width)), np.uint8)
    frames[:, 3:7, ::3] = 255
    rows = np.arange(2, 9)
    small = capture(scene, frames, cam, rng=7, rows=rows)
    old = render.SMALL_RENDER
    try:
        render.SMALL_RENDER = 0  # force the numba kernels
        big = capture(scene, frames, cam, rng=7, rows=rows)
    finally:
        render.SMALL_RENDER = old
    assert np.abs(small.astype(int) - big.astype(int)).max() <= 1  # float rounding at .5 at most
    assert (small == big).mean() > 0.999


def test_a_code_that_detects_nothing_is_refused():
    """gray-10 has d_min 1: every word is a codeword, so the loop verified every pixel unchecked."""
    with pytest.raises(ValueError, match=r"EDC needs a code that detects errors \(d_min >= 2\), got 'gray-10'"):
        EdcScheme("gray-10")
    assert EdcScheme("gray-10+crc5").code.d_min >= 2

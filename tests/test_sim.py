"""Simulator: image formation, noise model, fixed exposure, warping, shadows, GI, scenes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edge.codes import Code, digits_to_int, get_code
from edge.sim import (
    CameraModel, Geometry, capture, capture_code, code_profiles, make_scene, projector_irradiance, scene_names,
)

NOISELESS = dict(sigma_r=0.0, sigma_s=0.0)


def threshold_decode(cap, code: Code) -> np.ndarray:
    """Per-bit threshold decoder of a binary linear code with identity generator (Gray, binary)."""
    mid = (cap.white.astype(np.float32) + cap.black.astype(np.float32)) / 2
    bits = (cap.frames.astype(np.float32) > mid[None]).astype(np.int64)
    msg = digits_to_int(np.moveaxis(bits[: code.k], 0, -1))
    return code.column_of_message[msg].astype(np.int32)


# ------------------------------------------------------------------------------------ noise model

@pytest.mark.parametrize("level", [0.0, 0.3])
def test_noise_mean_and_variance_match_model(level):
    scene = make_scene("plane", 32, 32, texture=0.0, albedo=0.5)
    cam = CameraModel(bits=16, sigma_r=0.01, sigma_s=0.04, ambient=0.2, projector=0.6)
    frames = capture(scene, np.full((200, 1024), level, np.float32), cam, rng=1)
    x = frames.astype(np.float64) / cam.levels
    clean = 0.5 * (0.6 * level + 0.2)
    var_model = cam.sigma_r**2 + cam.sigma_s**2 * clean + 1.0 / (12 * cam.levels**2)
    n = x.size
    assert abs(x.mean() - clean) < 5 * np.sqrt(var_model / n)
    # sample variance of Gaussian data: std error ~ var * sqrt(2 / n)
    assert abs(x.var() - var_model) < 5 * var_model * np.sqrt(2.0 / n)


def test_quantisation_dtype_and_saturation():
    scene = make_scene("plane", 16, 16, texture=0.0, albedo=1.0)
    for bits, dtype in [(8, np.uint8), (10, np.uint16), (12, np.uint16), (16, np.uint16)]:
        cam = CameraModel(bits=bits, sigma_r=0.0, sigma_s=0.0, ambient=0.5, projector=2.0)
        f = capture(scene, np.ones((2, 1024), np.float32), cam, rng=0)
        assert f.dtype == dtype and f.shape == (2, 16, 16)
        assert (f == 2**bits - 1).all()  # saturated, clipped to full scale
    cam = CameraModel(bits=12, **NOISELESS, ambient=0.1, projector=0.0)
    f = capture(scene, np.zeros((1, 1024), np.uint8), cam, rng=0)
    assert (f == round(0.1 * 4095)).all()


def test_fixed_total_exposure_scaling():
    scene = make_scene("plane", 24, 16, texture=0.0, albedo=0.8)
    cam = CameraModel(bits=16, **NOISELESS, ambient=0.1, projector=0.5, total_exposure=10.0)
    gray = capture_code(scene, get_code("gray-10"), cam, rng=0)
    ecc = capture_code(scene, get_code("ecc-22-10"), cam, rng=0)
    assert gray.frames.shape[0] == 10 and ecc.frames.shape[0] == 22
    assert gray.exposure == pytest.approx(1.0) and ecc.exposure == pytest.approx(10 / 22)
    for c in (gray, ecc):
        assert c.white.mean() / cam.levels == pytest.approx(c.exposure * 0.8 * 0.6, abs=1e-4)
        assert c.black.mean() / cam.levels == pytest.approx(c.exposure * 0.8 * 0.1, abs=1e-4)
    assert gray.white.mean() / ecc.white.mean() == pytest.approx(2.2, rel=1e-3)
    # code frames hold only the black and white levels
    levels = np.unique(ecc.frames)
    assert set(levels.tolist()) <= {int(ecc.black[0, 0]), int(ecc.white[0, 0])}


def test_nary_code_rendered_with_intensity_levels():
    cb = np.array([[0, 1, 2], [2, 1, 0], [1, 1, 1]], np.uint8)
    code = Code(name="ternary-test", family="test", codebook=np.tile(cb, (3, 1))[:9], k=2, q=3)
    prof = code_profiles(code, 12, stripe=1)
    assert prof.shape == (3, 12)
    assert np.allclose(prof[:, 0], [0.0, 0.5, 1.0]) and np.allclose(prof[:, 1], [1.0, 0.5, 0.0])
    assert np.all(prof[:, 9:] == 0)  # columns beyond the code are dark
    prof2 = code_profiles(code, 12, stripe=2)
    assert np.array_equal(prof2[:, 0], prof2[:, 1]) and np.array_equal(prof2[:, 2], prof[:, 1])


# ------------------------------------------------------------------------------------------- warp

def test_plane_columns_are_analytic_and_warp_puts_them_at_the_right_pixel():
    geo = Geometry.default(64, 8)
    scene = make_scene("plane", 64, 8, depth=1.0)
    x = np.arange(64)
    expected = x - (geo.focal_px * geo.baseline_m / 1.0 - geo.doffs)
    assert np.allclose(scene.column[0], expected, atol=1e-3)
    assert np.array_equal(scene.column_int[3], np.floor(expected + 0.5).astype(np.int32))
    # a projector ramp: pattern value encodes the projector column
    ramp = (np.arange(1024) / 1023.0).astype(np.float32)[None]
    e = projector_irradiance(scene, ramp, CameraModel())
    assert np.allclose(e[0] * 1023.0, scene.column_int, atol=1e-3)


def test_row_dependent_frames_use_the_same_projector_row():
    scene = make_scene("plane", 32, 6)
    frames = np.zeros((1, 6, 1024), np.uint8)
    frames[0, 2, :] = 255
    e = projector_irradiance(scene, frames, CameraModel())
    assert np.all(e[0, 2] == 1.0) and np.all(np.delete(e[0], 2, axis=0) == 0.0)


@pytest.mark.parametrize("name", ["tilted-plane", "steps", "sphere", "flying"])
def test_gray_code_decodes_exactly_at_high_snr(name):
    scene = make_scene(name, 96, 64, seed=2)
    cam = CameraModel(bits=12, sigma_r=0.0005, sigma_s=0.002, ambient=0.02, projector=0.9)
    code = get_code("gray-10")
    col = threshold_decode(capture_code(scene, code, cam, rng=0), code)
    ok = scene.lit & (scene.albedo > 0.1)
    assert ok.sum() > 1000
    assert np.mean(col[ok] == scene.column_int[ok]) > 0.999


# ---------------------------------------------------------------------------------------- shadows

def test_shadows_get_no_projector_light():
    for name in ("steps", "sphere", "flying"):
        scene = make_scene(name, 160, 120, seed=1)
        assert 0 < (~scene.lit).sum() < scene.lit.size / 2, name
        cam = CameraModel(bits=16, **NOISELESS, ambient=0.0, projector=1.0)
        f = capture(scene, np.ones((1, 1024), np.uint8) * 255, cam, rng=0)[0]
        assert np.all(f[~scene.lit] == 0), name
        assert np.all(f[scene.lit] > 0), name
        assert np.all(scene.column_int[~scene.lit] == -1) and np.all(np.isnan(scene.column[~scene.lit]))


def test_step_shadow_matches_analytic_projector_occlusion():
    scene = make_scene("steps", 200, 4, steps=4)
    geo = scene.geometry
    z = scene.depth_m[0].astype(np.float64)
    sid = scene.object_id[0]
    col = np.arange(200) - (geo.focal_px * geo.baseline_m / z - geo.doffs)
    shadow = np.zeros(200, bool)
    ambiguous = np.zeros(200, bool)
    for step in np.unique(sid):
        seg = col[sid == step]
        lo, hi = seg.min() - 0.5, seg.max() + 0.5          # projector columns this step intercepts
        behind = z > z[sid == step][0]
        shadow |= behind & (col >= lo) & (col <= hi)
        ambiguous |= behind & (np.abs(col - lo) < 1.0) | behind & (np.abs(col - hi) < 1.0)
    assert shadow.sum() > 10
    assert np.array_equal(scene.lit[0][~ambiguous], ~shadow[~ambiguous])


def test_projector_frames_beyond_the_projector_are_dark_columns():
    scene = make_scene("plane", 32, 4)
    e = projector_irradiance(scene, np.ones((1, 200), np.float32), CameraModel())
    seen = scene.column_int[0]
    assert np.all(e[0, 0][seen < 200] == 1.0) and np.all(e[0, 0][seen >= 200] == 0.0)


# ------------------------------------------------------------------------------ global illumination

def test_interreflection_is_linear_and_masking_columns_removes_direct_and_indirect():
    scene = make_scene("v-groove", 128, 64, texture=0.0)
    assert scene.interreflection is not None and scene.indirect.mean() > 0.5
    cam = CameraModel()
    wp = scene.geometry.projector_width
    crease = int(np.argmax(scene.depth_m[0]))
    edge = (crease // 16 - 1) * 16          # patch-aligned: lit patches lie wholly on the left facet
    left_cols = scene.column_int[:, :edge]
    on_left = np.zeros((1, wp), np.float32)
    on_left[0, left_cols[left_cols >= 0].min(): left_cols.max() + 1] = 1.0
    on_right = np.clip(1.0 - on_left, 0, 1)
    e_all = projector_irradiance(scene, np.ones((1, wp), np.float32), cam)[0]
    e_left = projector_irradiance(scene, on_left, cam)[0]
    e_right = projector_irradiance(scene, on_right, cam)[0]
    assert np.allclose(e_left + e_right, e_all, atol=1e-5)                      # linear in the pattern
    left = np.s_[:, : edge - 2]
    right = np.s_[:, crease + 24:]
    assert e_all[:, : crease - 24].min() > 1.03                               # direct + indirect
    assert np.allclose(e_left[left], 1.0, atol=1e-3)                            # right facet dark: no bounce
    assert e_left[right].max() > 0.05 and np.all(e_left[right] < 0.6)           # indirect only
    dark = projector_irradiance(scene, np.zeros((1, wp), np.float32), cam)
    assert np.all(dark == 0.0)                                                  # all off: nothing at all


def test_scattering_blurs_the_pattern_inside_its_regions_only():
    scene = make_scene("scattering", 160, 120, seed=0)
    inside = scene.scattering > 0
    assert inside.any() and (~inside).any() and np.array_equal(scene.indirect, inside)
    stripes = (np.arange(1024) // 2 % 2).astype(np.float32)[None]
    e = projector_irradiance(scene, stripes, CameraModel())[0]
    assert np.isin(e[~inside], [0.0, 1.0]).all()
    core = cv2.erode(inside.astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    assert e[core].std() < 0.5 * e[~inside].std()


def test_defocus_blurs_in_projector_space():
    scene = make_scene("plane", 64, 4)
    stripes = (np.arange(1024) // 2 % 2).astype(np.float32)[None]
    sharp = projector_irradiance(scene, stripes, CameraModel())[0]
    blurred = projector_irradiance(scene, stripes, CameraModel(defocus_sigma=1.5))[0]
    assert np.isin(sharp, [0.0, 1.0]).all()
    assert blurred.std() < 0.5 * sharp.std() and abs(blurred.mean() - 0.5) < 0.05


# ----------------------------------------------------------------------------------------- scenes

def test_scenes_have_consistent_ground_truth():
    for name in scene_names():
        s = make_scene(name, 80, 60, seed=0)
        geo = s.geometry
        assert s.albedo.shape == (60, 80) and s.albedo.dtype == np.float32
        assert s.column_int.dtype == np.int32 and s.lit.dtype == bool and s.indirect.dtype == bool
        z = s.depth_m
        assert np.nanmin(z) >= 0.4 - 1e-6 and np.nanmax(z) <= 2.0 + 1e-6, name
        assert np.allclose(geo.depth_from_disparity(s.disparity), z, rtol=1e-4)
        x = np.arange(80)[None, :]
        assert np.allclose(s.column[s.lit], (x - s.disparity)[s.lit], atol=1e-3)
        assert np.array_equal(s.column_int >= 0, s.lit)


def test_scenes_are_deterministic_and_move_with_t():
    a = make_scene("flying", 96, 72, seed=5)
    b = make_scene("flying", 96, 72, seed=5)
    c = make_scene("flying", 96, 72, seed=6)
    for f in ("albedo", "depth_m", "column_int", "lit"):
        assert np.array_equal(getattr(a, f), getattr(b, f))
    assert not np.array_equal(a.depth_m, c.depth_m)
    moved = make_scene("flying", 96, 72, seed=5, t=1.0)
    assert not np.array_equal(a.depth_m, moved.depth_m)
    assert np.array_equal(moved.depth_m, make_scene("flying", 96, 72, seed=5, t=1.0).depth_m)
    p0, p1 = make_scene("plane", 8, 8), make_scene("plane", 8, 8, t=1.0)
    assert p1.depth_m[0, 0] == pytest.approx(p0.depth_m[0, 0] + 0.05)
    cam = CameraModel()
    f1 = capture(a, np.ones((2, 1024), np.float32), cam, rng=np.random.default_rng(3))
    f2 = capture(a, np.ones((2, 1024), np.float32), cam, rng=np.random.default_rng(3))
    assert np.array_equal(f1, f2)


# -------------------------------------------------------------------------------------- bad input

def test_bad_input_raises_one_clear_error():
    scene = make_scene("plane", 16, 8)
    frames = np.ones((1, 1024), np.float32)
    with pytest.raises(ValueError, match="exposure must be > 0"):
        capture(scene, frames, CameraModel(), rng=0, exposure=-1.0)
    with pytest.raises(ValueError, match="exposure must be > 0"):
        CameraModel(total_exposure=0.0)
    with pytest.raises(ValueError, match="bits must be one of"):
        CameraModel(bits=9)
    with pytest.raises(ValueError, match="sigma_s must be >= 0"):
        CameraModel(sigma_s=-0.1)
    with pytest.raises(ValueError, match="unknown scene 'nope'"):
        make_scene("nope", 16, 8)
    with pytest.raises(ValueError, match="unknown parameter"):
        make_scene("plane", 16, 8, radius=3)
    with pytest.raises(ValueError, match="projector has 1024 columns"):
        capture(scene, np.ones((1, 2048), np.float32), CameraModel(), rng=0)
    with pytest.raises(ValueError, match="must be in \\[0, 1\\]"):
        capture(scene, np.full((1, 1024), 255.0, np.float32), CameraModel(), rng=0)
    with pytest.raises(ValueError, match="rows; expected 8"):
        capture(scene, np.ones((1, 5, 1024), np.uint8), CameraModel(), rng=0)
    with pytest.raises(ValueError, match="covers projector columns 0..255"):
        capture_code(scene, get_code("gray-8"), CameraModel(), rng=0)


def test_extra_irradiance_must_be_one_frame_per_projector_frame():
    # a (1, H, W) or (H, W) array broadcast silently over the frames on the full path and failed with
    # numpy's broadcast error (or indexed the wrong axis) on the rows= path
    scene = make_scene("plane", 16, 8)
    frames = np.ones((2, 1024), np.float32)
    cam = CameraModel(**NOISELESS)
    good = np.full((2, 8, 16), 0.1, np.float32)
    np.testing.assert_array_equal(capture(scene, frames, cam, rng=0, rows=np.array([1, 5]), extra_irradiance=good),
                                  capture(scene, frames, cam, rng=0, extra_irradiance=good)[:, [1, 5]])
    for shape in [(1, 8, 16), (8, 16), (2, 8, 1), (3, 8, 16), (2, 9, 16)]:
        for rows in (None, np.array([1, 5])):
            with pytest.raises(ValueError, match=r"extra_irradiance must be \(m, H, W\)"):
                capture(scene, frames, cam, rng=0, rows=rows, extra_irradiance=np.zeros(shape, np.float32))

"""One bound of the noise sigmas: `edge.capture.MAX_SIGMA` (normalised units, 1 = full scale), which the
decoder's settings, the profiles and the simulator's camera read.

The profiles held ``[camera] sigma_r / sigma_s`` to [0, 1] while `DecodeSettings` took them up to
10; now both read `MAX_SIGMA` = 1, and each refusal names the field and the allowed range.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import edge.capture
from edge.codes import get_code
from edge.decode import DecodeSettings, decode
from edge.decode.settings import DEFAULT_SETTINGS, MAX_SIGMA, from_profile
from edge.decode.synthetic import make_capture
from edge.profiles import ProfileError, apply_update, load_profile
from edge.profiles.settings import CameraSettings
from edge.sim import CameraModel

RANGE = {"sigma_r": "sigma_r: expected 1e-06 <= sigma_r <= 1 (normalised units, 1 = full scale)",
         "sigma_s": "sigma_s: expected 0 <= sigma_s <= 1 (normalised units, 1 = full scale)"}


def test_the_profile_bound_is_the_decoder_bound():
    assert MAX_SIGMA == 1.0 and MAX_SIGMA is edge.capture.MAX_SIGMA
    hi = {f.name: f.metadata["hi"] for f in dataclasses.fields(CameraSettings) if f.name.startswith("sigma")}
    assert hi == {"sigma_r": MAX_SIGMA, "sigma_s": MAX_SIGMA}


@pytest.mark.parametrize("name", ["sigma_r", "sigma_s"])
def test_decode_settings_refuse_a_sigma_above_full_scale(name):
    assert getattr(DEFAULT_SETTINGS.replace(**{name: 1.0}), name) == 1.0  # the bound itself is allowed
    for bad in (1.5, 10.0, 4.3e250, -0.1):  # 10 passed before (the old bound)
        with pytest.raises(ValueError) as info:
            DecodeSettings(**{name: bad})
        assert str(info.value) == f"{RANGE[name]}, got {bad}"
    with pytest.raises(ValueError, match=r"^sigma_r: expected 1e-06 <= sigma_r <= 1 .*got 0.0$"):
        DecodeSettings(sigma_r=0.0)  # sigma_r > 0: the search divides by the variance


@pytest.mark.parametrize("name", ["sigma_r", "sigma_s"])
def test_decode_refuses_a_sigma_above_full_scale(name):
    code = get_code("ecc-22-10")
    cap = make_capture(code, np.full((2, 8), 40), rng=np.random.default_rng(0))
    with pytest.raises(ValueError) as info:
        decode(cap.frames, cap.white, cap.black, code, **{name: 2.0})
    assert str(info.value) == f"{RANGE[name]}, got 2.0"


@pytest.mark.parametrize("name", ["sigma_r", "sigma_s"])
def test_profiles_accept_what_the_decoder_accepts(name):
    """A profile takes a sigma exactly where `DecodeSettings` does (from_profile never refuses a
    validated profile); its error names the dotted key and both ends of the range."""
    p = load_profile()
    at = apply_update(p, {"camera": {name: MAX_SIGMA}})
    assert getattr(from_profile(at), name) == MAX_SIGMA
    for bad in (1.5, 10.0):
        with pytest.raises(ValueError):
            DecodeSettings(**{name: bad})
        with pytest.raises(ProfileError) as info:
            apply_update(p, {"camera": {name: bad}}, source="dev.toml")
        assert info.value.key == f"camera.{name}"
        assert str(info.value) == f"dev.toml: camera.{name}: expected a value >= 0 and <= 1, got {bad}"
    with pytest.raises(ProfileError, match=rf"camera\.{name}: expected a value >= 0 and <= 1, got -0.5"):
        apply_update(p, {"camera": {name: -0.5}})


def test_profile_range_errors_name_both_ends():
    """The profile engine states the whole range of a field with two ends (one with one end as before)."""
    p = load_profile()
    with pytest.raises(ProfileError, match=r"camera\.rate_hz: expected a value > 0 and <= 1e\+06, got -5.0"):
        apply_update(p, {"camera": {"rate_hz": -5.0}})
    with pytest.raises(ProfileError, match=r"camera\.exposure_us: expected a value > 0, got 0.0$"):
        apply_update(p, {"camera": {"exposure_us": 0.0}})


def _steep_noise_capture():
    """A capture (float32, 2000 pixels) whose mean levels all lie within 0.49..0.51 while their
    noise grows steeply with the level: the decoder's two-level split fits a shot-noise slope of
    about (1.5)**2, sqrt(beta) > 1 = `MAX_SIGMA`."""
    code = get_code("ecc-22-10")
    n, m = code.n, code.n + 2
    rng = np.random.default_rng(1)
    h, w = 40, 50
    x = np.linspace(0.49, 0.51, h * w)
    sd = np.sqrt((0.0005 + 4.0 * (x - 0.49)) / 0.36)
    z = rng.standard_normal((m // 2, h * w))
    vals = np.clip(x + sd * np.concatenate([z, -z]), 0.001, 0.999)
    vals = vals[:, rng.permutation(h * w)].astype(np.float32).reshape(m, h, w)
    return code, vals[:n], vals[n], vals[n + 1]


def test_a_fitted_noise_above_the_bound_does_not_refuse_the_capture():
    from edge.decode.posterior import split_levels

    code, f, wh, bl = _steep_noise_capture()
    assert np.sqrt(split_levels(f, wh, bl, 1.0)[2].beta) > MAX_SIGMA  # the premise
    d = decode(f, wh, bl, code)
    assert d.column.shape == wh.shape


@pytest.mark.parametrize("name", ["sigma_r", "sigma_s"])
def test_the_simulator_camera_takes_the_same_bound(name):
    assert getattr(CameraModel(**{name: MAX_SIGMA}), name) == MAX_SIGMA
    with pytest.raises(ValueError, match=rf"^camera: {name} must be <= 1 \(normalised units, 1 = full scale\), got 1.5$"):
        CameraModel(**{name: 1.5})

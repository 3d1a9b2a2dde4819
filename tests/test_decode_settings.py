"""The one decoder settings object: validation, options, profiles, backend choice."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode import DEFAULT_SETTINGS, DecodeSettings, decode
from edge.decode import backends
from edge.decode.settings import FIELDS, from_profile
from edge.decode.synthetic import make_capture
from edge.profiles import load_profile


def test_bad_values_name_the_field():
    for kw, name in (({"method": "best"}, "method"), ({"sigma_r": 0.0}, "sigma_r"),
                     ({"t_low": 0.5, "t_high": 0.2}, "t_low"), ({"backend": "tpu"}, "backend"),
                     ({"min_contrast": float("nan")}, "min_contrast"), ({"spatial_check": 1}, "spatial_check"),
                     # a huge sigma overflowed its square (OverflowError from inside decode, found by the full fuzz)
                     ({"sigma_s": 4.3e250}, "sigma_s: expected 0 <= sigma_s <= 1 "),
                     ({"sigma_r": 11.0}, "sigma_r: expected 1e-06 <= sigma_r <= 1 "),
                     # beyond float32, cast to inf with a RuntimeWarning inside decode
                     ({"min_contrast": 1e300}, "min_contrast: expected 0..1"),
                     ({"min_confidence": -0.5}, "min_confidence: expected 0..1")):
        with pytest.raises(ValueError, match=name):
            DecodeSettings(**kw)
    with pytest.raises(ValueError, match="unknown option.*colour"):
        DEFAULT_SETTINGS.replace(colour="red")


def test_level_source_splits_binary_codes_only_under_the_error_rule():
    s = DEFAULT_SETTINGS
    assert s.rule(False) == "error" and s.rule(True) == "confidence"
    assert s.level_source("error", 2) == "split"
    assert s.level_source("error", 3) == s.level_source("error", 8) == "calibration"  # q levels, not two
    assert s.level_source("confidence", 2) == "calibration"
    for levels in ("calibration", "refit"):
        assert all(s.replace(levels=levels).level_source(r, q) == levels for r in ("error", "confidence") for q in (2, 8))
    with pytest.raises(ValueError, match="rule"):
        s.level_source("auto", 2)
    # what decode reports it ran
    code = get_code("nary3-6")
    rng = np.random.default_rng(4)
    cap = make_capture(code, rng.integers(0, code.size, (12, 40)), rng=rng, albedo=0.6, sigma_s=0.02)
    d = decode(cap.frames, cap.white, cap.black, code)
    assert d.stats["rule"] == "error" and d.stats["levels"] == "auto" and d.stats["level_source"] == "calibration"
    code = get_code("ecc-15-10")
    cap = make_capture(code, rng.integers(0, code.size, (12, 40)), rng=rng, albedo=0.6, sigma_s=0.02)
    assert decode(cap.frames, cap.white, cap.black, code).stats["level_source"] == "split"


def test_options_equal_settings():
    code = get_code("ecc-15-10")
    rng = np.random.default_rng(3)
    cap = make_capture(code, rng.integers(0, code.size, (12, 40)), rng=rng, albedo=0.3, sigma_r=0.05)
    s = DEFAULT_SETTINGS.replace(method="list", min_confidence=0.2)
    a = decode(cap.frames, cap.white, cap.black, code, settings=s)
    b = decode(cap.frames, cap.white, cap.black, code, method="list", min_confidence=0.2)
    assert np.array_equal(a.column, b.column) and np.array_equal(a.confidence, b.confidence)
    with pytest.raises(ValueError, match="unknown option"):
        decode(cap.frames, cap.white, cap.black, code, thresold=0.1)


def test_profile_maps_every_field(tmp_path):
    p = load_profile("sim-dlp")
    s = from_profile(p)
    assert s.method == p.decoder.method and s.min_contrast == p.decoder.min_contrast
    assert s.sigma_s == p.camera.sigma_s and s.sigma_r == max(p.camera.sigma_r, 1e-4)
    assert set(FIELDS) - {"sigma_r", "sigma_s"} <= set(vars(p.decoder)), "a settings field a profile cannot express"


def test_profile_defaults_are_the_librarys():
    """One source of defaults: a [decoder] table with only the band decodes as `decode()` does
    (the camera's noise model aside), the profile layout documents those defaults, and the
    shipped column-code profiles set nothing but the method and the band."""
    import dataclasses
    import re
    import tomllib
    from pathlib import Path

    import edge.profiles.settings as profile_settings
    from edge.profiles.settings import build_profile, profile_to_dict

    base = profile_to_dict(load_profile("sim-dlp"))
    base["decoder"] = {"min_disparity": base["decoder"]["min_disparity"],
                       "max_disparity": base["decoder"]["max_disparity"]}
    p = build_profile(base)
    assert from_profile(p) == DEFAULT_SETTINGS.replace(sigma_r=max(p.camera.sigma_r, 1e-4), sigma_s=p.camera.sigma_s)
    assert from_profile(p).rule(False) == "error"
    shared = [f for f in dataclasses.fields(profile_settings.DecoderSettings) if f.name in FIELDS]
    assert {f.name for f in shared} == set(FIELDS) - {"sigma_r", "sigma_s"}
    assert all(f.default == getattr(DEFAULT_SETTINGS, f.name) for f in shared)
    layout = profile_settings.__doc__.split("[decoder]", 1)[1].split("[edc]", 1)[0]
    documented = dict(re.findall(r"^\s*(\w+) = (\S+)", layout, flags=re.M))
    assert {k for k in documented if k in FIELDS} >= {"method", "validity", "max_error", "levels", "min_contrast",
                                                      "min_confidence", "metric", "backend"}
    for key, text in documented.items():
        if key in FIELDS:
            assert tomllib.loads(f"v = {text}")["v"] == getattr(DEFAULT_SETTINGS, key), key
    root = Path(__file__).resolve().parents[1]
    for path in [*(root / "firmware_profiles").glob("*.toml"), root / "tests" / "data" / "profiles" / "test-small.toml"]:
        data = tomllib.loads(path.read_text())
        if data["projector"].get("kind", "columns") == "columns":
            assert set(data["decoder"]) <= {"method", "min_disparity", "max_disparity"}, path.name


def test_auto_backend_falls_back_with_a_log_line(caplog, monkeypatch):
    monkeypatch.setattr(backends, "available", lambda name: name == "cpu")
    monkeypatch.setattr(backends, "_FELL_BACK", [])
    with caplog.at_level(logging.INFO, logger="edge.decode"):
        assert backends.resolve("auto") == "cpu"
    assert "no CUDA device" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="edge.decode"):
        assert backends.resolve("auto") == "cpu"
    assert "no CUDA device" not in caplog.text, "the fallback is said once per process"
    assert backends.resolve("cpu") == "cpu"
    with pytest.raises(ValueError, match="backend"):
        backends.resolve("gpu")

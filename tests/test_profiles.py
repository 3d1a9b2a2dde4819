"""Firmware profiles: shipped files load, validation errors name file, key and reason."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from edge.cli import main as cli_main
from edge.profiles import (
    DEFAULT_PROFILE,
    Profile,
    ProfileError,
    apply_update,
    changed_keys,
    list_profiles,
    load_profile,
    profile_from_dict,
    profile_to_dict,
)

SHIPPED = ["sim-dlp", "oak-d-pro", "event-dots", "light-curtain"]


def test_shipped_profiles_load_and_round_trip():
    assert set(SHIPPED) <= set(list_profiles())
    for name in SHIPPED:
        p = load_profile(name)
        assert isinstance(p, Profile) and p.name == name
        d = profile_to_dict(p)
        assert json.loads(json.dumps(d)) == d  # JSON-able
        assert profile_from_dict(d) == p
        assert p.zenoh.key("depth") == f"sl/{name}/depth"


def test_default_profile_is_sim_dlp_with_the_design_card_settings():
    p = load_profile()
    assert DEFAULT_PROFILE == "sim-dlp" and p.name == "sim-dlp"
    assert (p.camera.width, p.camera.height, p.camera.rate_hz) == (640, 480, 120.0)
    assert p.projector.width == 1024
    assert p.code.name == "ecc-22-10" and p.decoder.method == "soft"
    assert p.sensor.backend == "sim"
    assert p.zenoh.mode == "peer" and p.zenoh.multicast_scouting is False
    assert p.zenoh.listen == ("tcp/127.0.0.1:7451",)
    assert p.geometry.doffs == p.geometry.cx_projector - p.geometry.cx_camera


def test_profiles_are_frozen():
    p = load_profile()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.camera.rate_hz = 10.0  # type: ignore[misc]


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "dev.toml"
    path.write_text(text)
    return path


def _with(tmp_path: Path, old: str, new: str) -> Path:
    base = Path(load_profile().source).read_text()
    assert old in base
    return _write(tmp_path, base.replace(old, new, 1))


@pytest.mark.parametrize(
    "old, new, key, reason",
    [
        ("sigma_s = 0.015", "sigma_s = 0.015\ngain = 2", "camera.gain", "unknown key"),
        ("rate_hz = 120.0\nbits", "rate_hz = \"fast\"\nbits", "camera.rate_hz", "expected a number, got string"),
        ("rate_hz = 120.0\nbits", "rate_hz = -5.0\nbits", "camera.rate_hz", "expected a value > 0"),
        ("bits = 8", "bits = 9", "camera.bits", "expected one of 8, 10, 12, 16"),
        ('name = "ecc-22-10"', 'name = "nosuch-10"', "code.name", "unknown code 'nosuch-10'"),
        ('source = ""', 'source = "10x1"', "code.source", "matching"),
        ('source = ""', 'source = "0000"', "code.source", "at least one '1'"),
        ('source = ""', 'source = "1111"', "code.source", "at least one '0'"),  # never off: no code
        ('method = "soft"', 'method = "magic"', "decoder.method", "expected one of"),
        ("max_disparity = -64", "max_disparity = -200", "decoder.max_disparity", ">= decoder.min_disparity"),
        ("min_disparity = -176", "min_disparity = -400", "decoder.min_disparity", "min_disparity + doffs > 0"),
        ("width = 1024", "width = 2048", "projector.width", "expected <= 1024 columns"),
        ("exposure_us = 8000.0", "exposure_us = 9000.0", "camera.exposure_us", "frame period"),
        ('listen = ["tcp/127.0.0.1:7451"]', 'listen = ["127.0.0.1:7451"]', "zenoh.listen[0]", "matching"),
        ('listen = ["tcp/127.0.0.1:7451"]', 'listen = "tcp/127.0.0.1:7451"', "zenoh.listen", "array of strings"),
        ("multicast_scouting = false", "multicast_scouting = 0", "zenoh.multicast_scouting", "true or false"),
        ('mode = "peer"', 'mode = "client"', "zenoh.connect", "client mode"),
        ('compression = "zstd"', 'compression = "gzip"', "recording.compression", "expected one of"),
        ("chunk_size = 4194304", "chunk_size = 10", "recording.chunk_size", ">= 4096"),
        ('backend = "sim"', 'backend = "usb"', "sensor.backend", "expected one of"),
    ],
)
def test_bad_values_give_one_error_with_file_key_and_reason(tmp_path, old, new, key, reason):
    path = _with(tmp_path, old, new)
    with pytest.raises(ProfileError) as info:
        load_profile(path)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.key == key and reason in err.reason, str(err)
    message = str(err)
    assert message.startswith(f"{path}: {key}: ") and "\n" not in message


def test_missing_table_and_malformed_toml(tmp_path):
    path = _write(tmp_path, 'name = "x"\n')
    with pytest.raises(ProfileError, match=r"dev\.toml: projector: missing required table"):
        load_profile(path)
    path = _write(tmp_path, 'name = "x"\n[camera\n')
    with pytest.raises(ProfileError, match=r"dev\.toml: not valid TOML"):
        load_profile(path)
    with pytest.raises(FileNotFoundError, match="no profile named 'nope'"):
        load_profile("nope")


def test_apply_update_merges_validates_and_keeps_the_original():
    p = load_profile()
    q = apply_update(p, {"decoder": {"method": "hard"}, "edc": {"rounds": 2}})
    assert q.decoder.method == "hard" and q.edc.rounds == 2
    assert p.decoder.method == "soft" and p.edc.rounds == 0
    assert changed_keys(p, q) == ["decoder.method", "edc.rounds"]
    assert q.camera == p.camera
    with pytest.raises(ProfileError, match=r"^update: decoder\.methd: unknown key"):
        apply_update(p, {"decoder": {"methd": "hard"}})
    with pytest.raises(ProfileError, match=r"^update: edc\.rounds: expected an integer, got string"):
        apply_update(p, {"edc": {"rounds": "2"}})
    with pytest.raises(ProfileError, match=r"expected a table"):
        apply_update(p, {"decoder": 3})
    with pytest.raises(ProfileError, match=r"expected a table"):
        apply_update(p, [1, 2])  # type: ignore[arg-type]


def test_profile_from_dict_uses_the_given_source_and_defaults_device_to_name():
    d = profile_to_dict(load_profile())
    d["name"] = "bench-2"
    del d["zenoh"]["device"]
    p = profile_from_dict(d, source="zenoh config")
    assert p.zenoh.device == "bench-2" and p.source == "zenoh config"
    d["camera"]["width"] = True
    with pytest.raises(ProfileError, match=r"^zenoh config: camera\.width: expected an integer, got boolean"):
        profile_from_dict(d, source="zenoh config")


def test_profile_search_path_env(tmp_path, monkeypatch):
    base = Path(load_profile().source).read_text()
    (tmp_path / "mine.toml").write_text(base.replace('name = "sim-dlp"', 'name = "mine"', 1))
    monkeypatch.setenv("EDGE_PROFILES_PATH", str(tmp_path))
    assert "mine" in list_profiles()
    assert load_profile("mine").zenoh.device == "sim-dlp"


def test_cli_profiles(tmp_path, capsys):
    assert cli_main(["profiles", "list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in SHIPPED)
    assert cli_main(["profiles", "show", "sim-dlp"]) == 0
    out = capsys.readouterr().out
    shown = json.loads(out.split("\n", 1)[1])
    assert shown == profile_to_dict(load_profile())
    bad = _with(tmp_path, "bits = 8", "bits = 7")
    assert cli_main(["profiles", "check", "sim-dlp", str(bad)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("ok: ") and out[1].startswith("error: ") and "camera.bits" in out[1]
    assert cli_main(["profiles", "show", "nope"]) == 2


def test_edc_rounds_need_a_code_that_detects_errors_and_a_column_projector():
    """edc.rounds > 0 with gray-10 (d_min 1: every word is a codeword) published every pixel as
    verified at confidence 255; with ecc-31-10 / nary3-6 the check passed and `edge run` refused;
    on dot and line projectors it was silently ignored."""
    from edge.runtime.warmup import switchable_variants

    p = load_profile()
    assert apply_update(p, {"edc": {"rounds": 2}}).edc.rounds == 2  # ecc-22-10: d_min 8, 22 frames
    for code, why in (("gray-10", "its d_min is 1"), ("ecc-31-10", "it has 31 frames"), ("nary3-6", "it is not binary")):
        width = 729 if code == "nary3-6" else p.projector.width
        q = apply_update(p, {"code": {"name": code}, "projector": {"width": width}})
        with pytest.raises(ProfileError, match=rf"edc\.rounds: expected 0 with code '{code}'.*{why}"):
            apply_update(q, {"edc": {"rounds": 1}})
        assert "edc" not in [label for label, _ in switchable_variants(q)]  # no EDC variant to warm
    for name, kind in (("light-curtain", "line"), ("oak-d-pro", "dots"), ("event-dots", "dots")):
        with pytest.raises(ProfileError, match=rf"edc\.rounds: expected 0 for a '{kind}' projector"):
            apply_update(load_profile(name), {"edc": {"rounds": 2}})

"""Profiles that `edge profiles check` used to accept but that fail or make nonsense are rejected
with one line naming the file, the key and the reason; binary / latin-1 files are named and the
rest of the file list is still checked."""

from __future__ import annotations

import pytest

from edge.cli import main
from edge.profiles import ProfileError, apply_update, load_profile
from edge.profiles.settings import decoder_methods

TEST_PROFILE = "tests/data/profiles/test-small.toml"

# (update over test-small, blamed key, words of the reason).  The first eleven ran with 0 % valid
# depth (edge run --stacks 1 on the simulator) before they were rejected.
NONSENSE = [
    ({"geometry": {"baseline_m": 1e-300}}, "geometry.baseline_m", "depth output range"),
    ({"geometry": {"baseline_m": 100.0}}, "geometry.baseline_m", "depth output range"),
    ({"geometry": {"focal_px": 1e-6}}, "geometry.baseline_m", "depth output range"),
    ({"geometry": {"focal_px": 1e6}}, "geometry.baseline_m", "depth output range"),
    ({"geometry": {"cx_camera": -1e5}}, "geometry.baseline_m", "depth output range"),
    ({"geometry": {"cx_projector": 1e5}}, "geometry.baseline_m", "depth output range"),
    ({"projector": {"stripe": 4096}}, "projector.stripe", "at least two codewords"),
    ({"decoder": {"min_disparity": 1000, "max_disparity": 2000}}, "decoder.min_disparity", "meet the projector"),
    ({"geometry": {"cx_projector": 400.0}, "decoder": {"min_disparity": -300, "max_disparity": -290}},
     "decoder.max_disparity", "meet the projector"),
    ({"decoder": {"min_contrast": 1.0}}, "decoder.min_contrast", "< 1"),
    ({"sim": {"projector": 0.0}}, "sim.projector", "decoder.min_contrast"),
    # no effect, or a failure at run time
    ({"decoder": {"min_confidence": 1.0}}, "decoder.min_confidence", "< 1"),
    ({"decoder": {"method": "curtain"}}, "decoder.method", "for a 'columns' projector"),
    ({"decoder": {"method": "block-match"}}, "decoder.method", "for a 'columns' projector"),
    ({"camera": {"rate_hz": 0.001, "exposure_us": 100.0}}, "camera.rate_hz", ">= 1 Hz"),
    ({"projector": {"rate_hz": 0.01}}, "projector.rate_hz", ">= 1 Hz"),
    ({"zenoh": {"status_period_s": 1e-9}}, "zenoh.status_period_s", ">= 0.05"),
    ({"camera": {"width": 1}}, "camera.width", ">= 2"),
    ({"sim": {"scene": "flat"}}, "sim.scene", "expected one of"),
]


@pytest.mark.parametrize("update, key, reason", NONSENSE)
def test_nonsense_is_rejected_naming_key_and_reason(update, key, reason):
    with pytest.raises(ProfileError) as info:
        apply_update(load_profile(TEST_PROFILE), update)
    assert info.value.key == key and reason in info.value.reason, str(info.value)
    assert "\n" not in str(info.value)


def test_long_source_code_is_bounded_by_the_stack_budget():
    with pytest.raises(ProfileError, match=r"code\.source: expected a stack of at most .* 64-slot source code"):
        apply_update(load_profile("sim-dlp"), {"code": {"source": "1" * 63 + "0"}})
    apply_update(load_profile("sim-dlp"), {"code": {"source": "1101"}})   # a short one still passes


def test_method_lists_have_one_source():
    from edge.decode import METHODS

    assert decoder_methods("columns") == tuple(METHODS)
    assert "list+median" in decoder_methods("columns")
    p = apply_update(load_profile(TEST_PROFILE), {"decoder": {"method": "list+median"}})   # reachable now
    assert p.decoder.method == "list+median"
    assert decoder_methods("dots") == ("block-match",) and decoder_methods("line") == ("curtain",)
    with pytest.raises(ProfileError, match="decoder.method: expected one of 'block-match'"):
        apply_update(load_profile("oak-d-pro"), {"decoder": {"method": "soft"}})


def test_check_names_binary_and_latin1_files_and_goes_on(tmp_path, capsys):
    latin1 = tmp_path / "latin1.toml"
    latin1.write_bytes('name = "café"\n'.encode("latin-1"))
    binary = tmp_path / "binary.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    rc = main(["profiles", "check", str(latin1), str(binary), TEST_PROFILE])
    out = capsys.readouterr().out.splitlines()
    assert rc == 1 and len(out) == 3, out
    assert out[0].startswith(f"error: {latin1}: ") and "not UTF-8" in out[0]
    assert out[1].startswith(f"error: {binary}: ") and "not UTF-8" in out[1]
    assert out[2] == f"ok: {TEST_PROFILE}"

"""Corrupt recordings: `edge replay`, `edge replay --recover` and `edge run --sensor replay` give an
honest result or one clear error line (exit 2), never a traceback, hang or silent wrong success.

The CI sample runs 2 mutants of every kind of tools/faults_recordings.py (`python
tools/faults_recordings.py --full` runs 120); the tests below pin the individual failures.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import faults_recordings as fr  # noqa: E402

PROFILE = str(ROOT / "tests" / "data" / "profiles" / "test-small.toml")


@pytest.fixture(scope="module")
def lays(tmp_path_factory):
    return fr.bases(tmp_path_factory.mktemp("bases"))


def _write(tmp_path: Path, name: str, data: bytes) -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


def _one_error_line(rc, stderr, exc) -> str:
    assert exc is None, exc
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "error:" in lines[0] and "Traceback" not in stderr, (rc, stderr)
    return lines[0]


def test_ci_sample_of_every_mutation_kind():
    results = fr.run_suite(per_kind=2, sensor_every=4, seed=20261201)
    assert sum(r.trials for r in results) == 2 * len(fr.KINDS)
    for r in results:
        assert r.bad == 0, (r.kind, r.outcomes, r.examples)
        assert r.held_short == 0, (r.kind, r.examples)   # every intact chunk salvaged


def test_flipped_byte_in_zstd_chunk_is_one_error_and_salvage_goes_past_it(tmp_path, lays):
    lay = lays["zstd"]
    start, length = lay.chunks[0]                          # chunk 0 also defines the channels
    data = bytearray(lay.data)
    data[start + length // 2] ^= 0x5A
    bad = _write(tmp_path, "flip.mcap", bytes(data))
    rc, out, err, exc, _ = fr.cli(["replay", str(bad)])
    line = _one_error_line(rc, err, exc)
    assert "corrupt chunk" in line and "bit for bit" not in out
    rec = tmp_path / "rec.mcap"
    rc, out, err, exc, _ = fr.cli(["replay", "--recover", "--out", str(rec), str(bad)])
    assert exc is None and "1 corrupt chunk(s) skipped" in out, out + err
    assert fr.library_accepts(rec)
    assert fr._raw_frames(rec) == lay.frames - lay.frames_in_chunk[0] > 0


def test_reader_rejects_what_the_mcap_library_rejects(tmp_path, lays):
    data = lays["raw"].data
    for name, mutant in (("cut-magic", data[:-3]), ("appended", data + b"\x00garbage"),
                         ("summary", data[:lays["raw"].summary_start + 20] + bytes([data[lays["raw"].summary_start + 20] ^ 1])
                          + data[lays["raw"].summary_start + 21:])):
        p = _write(tmp_path, f"{name}.mcap", mutant)
        assert not fr.library_accepts(p)
        rc, out, err, exc, _ = fr.cli(["replay", str(p)])
        _one_error_line(rc, err, exc)
        assert "bit for bit" not in out, name


def test_profile_sha256_is_checked(tmp_path, lays):
    lay = lays["zstd"]
    a, b = lay.profile_json
    data = bytearray(lay.data)
    pos = data.find(b'"rate_hz":120.0', a, b) + len('"rate_hz":12')
    data[pos] = ord("5")                                    # still valid JSON and a valid profile
    p = _write(tmp_path, "profile.mcap", bytes(data))
    rc, out, err, exc, _ = fr.cli(["replay", str(p)])
    assert "sha256" in _one_error_line(rc, err, exc)


def test_directory_as_file_is_one_clear_error(tmp_path):
    d = tmp_path / "adir.mcap"
    d.mkdir()
    for argv in (["replay", str(d)], ["replay", "--recover", str(d)],
                 ["run", "--sensor", "replay", "--replay", str(d), "--no-zenoh", "--profile", PROFILE]):
        rc, out, err, exc, _ = fr.cli(argv)
        assert "directory" in _one_error_line(rc, err, exc), argv


def test_sensor_replay_surfaces_crc_errors_and_truncation(tmp_path, lays):
    lay = lays["raw"]
    start, length = lay.chunks[len(lay.chunks) // 2]
    data = bytearray(lay.data)
    data[start + length - 100] ^= 0xFF
    for name, mutant in (("crc", bytes(data)), ("cut", lay.data[: len(lay.data) * 2 // 3])):
        p = _write(tmp_path, f"{name}.mcap", mutant)
        rc, out, err, exc, _ = fr.cli(["run", "--sensor", "replay", "--replay", str(p), "--no-zenoh", "--max-speed",
                                       "--quiet", "--profile", PROFILE])
        line = _one_error_line(rc, err, exc)
        assert "truncated or corrupt MCAP" in line, line

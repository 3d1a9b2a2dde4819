"""MCAP recording: round trip, CRCs, truncation, recovery (including a SIGKILLed writer)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, DataEnd
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.stream_reader import StreamReader

from edge.io.mcap import (
    NotMcapError,
    ProfileMismatchError,
    Recorder,
    RecordingError,
    RecordingReader,
    TruncatedRecordingError,
    recover,
)
from edge.profiles import apply_update, load_profile

H, W = 48, 64
N_STACKS, PER_STACK = 6, 5


def _image(seq: int, dtype=np.uint8) -> np.ndarray:
    hi = 256 if dtype == np.uint8 else 4096
    return np.random.default_rng(seq).integers(0, hi, (H, W), dtype=dtype)


def _depth(stack: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1000 + stack)
    return rng.integers(0, 65536, (H, W), dtype=np.uint16), rng.integers(0, 256, (H, W), dtype=np.uint8)


def _record(path: Path, profile, *, dtype=np.uint8, chunk_size=64 * 1024, compression=None) -> None:
    t0 = 1_700_000_000_000_000_000
    with Recorder(path, profile, sensor_metadata={"backend": "test", "serial": 42},
                  chunk_size=chunk_size, compression=compression) as rec:
        seq = 0
        for s in range(N_STACKS):
            for i in range(PER_STACK):
                role = "white" if i == 0 else "pattern"
                rec.write_raw(_image(seq, dtype), sequence=seq, timestamp_ns=t0 + seq * 1000, stack=s,
                              projector_frame=i, exposure_us=250.0, role=role, gain=2)
                seq += 1
            rec.write_stack({"stack": s, "frames": PER_STACK}, timestamp_ns=t0 + seq * 1000)
            d, c = _depth(s)
            rec.write_depth(d, c, timestamp_ns=t0 + seq * 1000, stack=s, sequence=s)


@pytest.fixture(scope="module")
def profile():
    return load_profile("sim-dlp")


@pytest.fixture(scope="module")
def recording(tmp_path_factory, profile):
    path = tmp_path_factory.mktemp("mcap") / "rec.mcap"
    _record(path, profile)
    return path


@pytest.mark.parametrize("dtype, compression", [(np.uint8, "zstd"), (np.uint16, "lz4"), (np.uint8, "none")])
def test_round_trip_is_bit_exact(tmp_path, profile, dtype, compression):
    path = tmp_path / "rt.mcap"
    _record(path, profile, dtype=dtype, compression=compression)
    reader = RecordingReader(path, expected_profile=profile)
    assert reader.complete and reader.profile == profile
    assert reader.sensor_metadata == {"backend": "test", "serial": "42"}
    frames = list(reader.frames())
    assert len(frames) == N_STACKS * PER_STACK
    for seq, f in enumerate(frames):
        assert f.image.dtype == dtype and np.array_equal(f.image, _image(seq, dtype))
        assert (f.sequence, f.stack, f.projector_frame) == (seq, seq // PER_STACK, seq % PER_STACK)
        assert f.exposure_us == 250.0 and f.info["gain"] == 2
        assert f.role == ("white" if seq % PER_STACK == 0 else "pattern")
    stacks = list(reader.stacks())
    assert [s.stack for s in stacks] == list(range(N_STACKS))
    for s in stacks:
        assert s.images.shape == (PER_STACK, H, W) and s.info == {"stack": s.stack, "frames": PER_STACK}
        d, c = _depth(s.stack)
        assert s.output is not None and s.output.depth_mm.dtype == np.uint16
        assert np.array_equal(s.output.depth_mm, d) and np.array_equal(s.output.confidence, c)


def test_file_opens_with_mcap_summary_and_foxglove_schemas(recording, profile):
    with open(recording, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None
        names = {s.name: s.encoding for s in summary.schemas.values()}
        assert names["foxglove.RawImage"] == "protobuf"
        assert names["foxglove.CameraCalibration"] == "protobuf"
        topics = {c.topic for c in summary.channels.values()}
        dev = profile.zenoh.device
        assert {f"/{dev}/raw", f"/{dev}/depth", f"/{dev}/confidence", f"/{dev}/calibration",
                f"/{dev}/stack"} <= topics
        # start: calibration + frame tree; per stack: raw + raw_info per frame, stack, output_info, depth,
        # confidence and the calibration of that depth map
        assert summary.statistics.message_count == 2 + N_STACKS * (2 * PER_STACK + 5)
        assert all(c.compression == "zstd" for c in summary.chunk_indexes)
        assert len(summary.chunk_indexes) > 1
        metadata = {m.name for m in reader.iter_metadata()}
        assert "edge.profile" in metadata
        assert [a.name for a in reader.iter_attachments()] == ["profile.json"]
        # every message decodes with the CRC-validating reader
        assert sum(1 for _ in reader.iter_messages()) == summary.statistics.message_count
    with open(recording, "rb") as f:
        records = list(StreamReader(f, emit_chunks=True).records)
    chunk_records = [r for r in records if isinstance(r, Chunk)]
    assert chunk_records and all(c.uncompressed_crc != 0 for c in chunk_records)
    assert next(r for r in records if isinstance(r, DataEnd)).data_section_crc != 0
    calib = next(m.value for m in RecordingReader(recording).messages() if m.topic.endswith("/calibration"))
    assert list(calib.K) == [profile.geometry.focal_px, 0, profile.geometry.cx_camera,
                             0, profile.geometry.focal_px, profile.geometry.cy, 0, 0, 1]


def test_crc_mismatch_is_reported(tmp_path, profile):
    # an uncompressed file: a flipped byte inside a frame's pixels still parses as MCAP, so the
    # chunk's CRC is the only thing that can catch it (in a zstd chunk decompression fails first)
    plain = tmp_path / "plain.mcap"
    _record(plain, profile, compression="none")
    data = bytearray(plain.read_bytes())
    at = data.find(_image(17).tobytes())
    assert at > 0
    data[at + 100] ^= 0xFF
    bad = tmp_path / "flipped.mcap"
    bad.write_bytes(bytes(data))
    with open(bad, "rb") as f:  # without CRC checks every record still parses
        assert sum(1 for _ in make_reader(f, validate_crcs=False).iter_messages()) == 2 + N_STACKS * (2 * PER_STACK + 5)
    with pytest.raises(TruncatedRecordingError, match=r"truncated or corrupt MCAP at byte \d+ of \d+"
                                                      r".*CRC mismatch"):
        list(RecordingReader(bad).frames())


def test_truncated_file_yields_readable_part_then_one_clear_error(tmp_path, recording):
    data = recording.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    reader = RecordingReader(cut)
    assert not reader.complete and reader.profile is not None
    got = []
    with pytest.raises(TruncatedRecordingError) as info:
        for f in reader.frames():
            got.append(f)
    err = info.value
    assert 0 < len(got) < N_STACKS * PER_STACK
    assert all(np.array_equal(f.image, _image(f.sequence)) for f in got)
    assert "\n" not in str(err) and f"of {len(data) * 6 // 10}" in str(err)
    assert err.messages > len(got) and 0 < err.offset < err.total
    # lenient mode: same frames, no exception, the problem kept
    lenient = RecordingReader(cut, strict=False)
    assert len(list(lenient.frames())) == len(got)
    assert lenient.problem == str(err)


def test_non_mcap_and_other_profile_errors(tmp_path, recording, profile):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"PK\x03\x04 this is a zip, not mcap")
    with pytest.raises(NotMcapError, match=r"junk\.mcap: not an MCAP file"):
        RecordingReader(junk)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(NotMcapError, match="file size 0 bytes"):
        RecordingReader(empty)
    with pytest.raises(ProfileMismatchError, match=r"recorded with profile 'sim-dlp', expected 'oak-d-pro'"):
        RecordingReader(recording, expected_profile=load_profile("oak-d-pro"))
    with pytest.raises(ProfileMismatchError, match=r"differs from the expected one in decoder\.method"):
        RecordingReader(recording, expected_profile=apply_update(profile, {"decoder": {"method": "hard"}}))
    # settings that do not affect decoding are not a mismatch: the file opens with its own profile
    other_port = apply_update(profile, {"zenoh": {"listen": ["tcp/127.0.0.1:9"]}})
    reader = RecordingReader(recording, expected_profile=other_port)
    assert reader.profile == profile != other_port and len(list(reader.frames())) == N_STACKS * PER_STACK
    assert issubclass(NotMcapError, RecordingError) and issubclass(RecordingError, ValueError)


def test_recorder_finishes_on_exception_and_rejects_bad_input(tmp_path, profile):
    path = tmp_path / "exc.mcap"
    with pytest.raises(RuntimeError):
        with Recorder(path, profile) as rec:
            rec.write_raw(_image(0), sequence=0, timestamp_ns=1, stack=0, projector_frame=0)
            raise RuntimeError("boom")
    reader = RecordingReader(path)
    assert reader.complete and len(list(reader.frames())) == 1
    with pytest.raises(ValueError, match="is finished"):
        rec.write_raw(_image(0), sequence=1, timestamp_ns=2, stack=0, projector_frame=0)
    rec.finish()  # idempotent
    with Recorder(tmp_path / "bad.mcap", profile) as rec:
        with pytest.raises(ValueError, match=r"expected an \(H, W\) uint8 or uint16 image"):
            rec.write_raw(np.zeros((2, 3, 4), np.uint8), sequence=0, timestamp_ns=0, stack=0, projector_frame=0)
        with pytest.raises(ValueError, match="expected depth uint16"):
            rec.write_depth(np.zeros((4, 4), np.float32), np.zeros((4, 4), np.uint8), timestamp_ns=0,
                            stack=0, sequence=0)


def test_recover_file_cut_mid_chunk(tmp_path, recording):
    data = recording.read_bytes()
    with open(recording, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    # cut in the middle of the third chunk: the first two survive
    third = sorted(chunks, key=lambda c: c.chunk_start_offset)[2]
    cut_at = third.chunk_start_offset + third.chunk_length // 2
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:cut_at])
    out = tmp_path / "recovered.mcap"
    report = recover(cut, out)
    assert report.chunks == 2 and not report.complete_input
    assert report.recovered_bytes == third.chunk_start_offset
    assert "dropped" in str(report) and "file ends" in report.reason
    reader = RecordingReader(out)
    assert reader.complete and reader.profile == RecordingReader(recording).profile
    frames = list(reader.frames())
    assert len(frames) == report.topics["/sim-dlp/raw"] > 0
    assert all(np.array_equal(f.image, _image(f.sequence)) for f in frames)
    # a complete input is copied whole
    full = recover(recording, tmp_path / "copy.mcap")
    assert full.complete_input and full.messages == 2 + N_STACKS * (2 * PER_STACK + 5)
    with pytest.raises(NotMcapError):
        recover(_junk(tmp_path), tmp_path / "x.mcap")


def _junk(tmp_path: Path) -> Path:
    p = tmp_path / "junk.bin"
    p.write_bytes(b"\x00" * 100)
    return p


_WRITER = textwrap.dedent(
    """
    import sys, numpy as np
    from edge.io.mcap import Recorder
    from edge.profiles import load_profile
    rec = Recorder(sys.argv[1], load_profile("sim-dlp"), chunk_size=32 * 1024)
    seq = 0
    while True:
        for i in range(5):
            img = np.random.default_rng(seq).integers(0, 256, (48, 64), dtype=np.uint8)
            rec.write_raw(img, sequence=seq, timestamp_ns=seq, stack=seq // 5, projector_frame=i)
            seq += 1
        if seq == 200:
            print("ready", flush=True)
    """
)


def test_sigkilled_writer_is_recoverable(tmp_path):
    path = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.strip() == "ready", f"writer did not start: {line!r}"
        time.sleep(0.2)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    reader = RecordingReader(path)
    assert not reader.complete
    with pytest.raises(TruncatedRecordingError):
        list(reader.frames())
    out = tmp_path / "recovered.mcap"
    report = recover(path, out)
    assert not report.complete_input and report.chunks >= 3 and report.messages > 0
    recovered = RecordingReader(out)
    assert recovered.complete and recovered.profile.name == "sim-dlp"
    frames = list(recovered.frames())
    assert len(frames) >= 200
    assert [f.sequence for f in frames] == list(range(len(frames)))  # no gaps, in order
    assert all(np.array_equal(f.image, np.random.default_rng(f.sequence).integers(0, 256, (H, W), dtype=np.uint8))
               for f in frames)


def test_recorder_extra_channel_public_api(tmp_path, profile):
    path = tmp_path / "extra.mcap"
    schema = b'{"type": "object"}'
    with Recorder(path, profile) as rec:
        cid = rec.register_channel("extra", "edge.Extra", "json", schema)
        assert rec.register_channel("extra", "edge.Extra", "json", schema) == cid  # idempotent
        with pytest.raises(ValueError, match="another schema"):
            rec.register_channel("extra", "edge.Other", "json", schema)
        with pytest.raises(ValueError, match="another schema"):
            rec.register_channel("raw", "edge.Extra", "json", schema)  # standard leaf
        with pytest.raises(ValueError, match="message encoding"):
            rec.register_channel("more", "edge.Extra", "cbor", schema)
        with pytest.raises(ValueError, match="register_channel"):
            rec.write_message(cid + 100, b"{}", log_time_ns=1)
        rec.write_message(cid, b'{"a": 1}', log_time_ns=5, sequence=9)
        rec.write_message(cid, b'{"a": 2}', log_time_ns=6)
        topic = rec.topics["extra"]
    with pytest.raises(ValueError, match="finish"):
        rec.write_message(cid, b"{}", log_time_ns=7)
    assert topic == f"/{profile.zenoh.device}/extra"
    with open(path, "rb") as f:
        got = [(s.name, s.encoding, c.message_encoding, m.log_time, m.sequence, m.data)
               for s, c, m in make_reader(f).iter_messages(topics=[topic])]
    assert got == [("edge.Extra", "jsonschema", "json", 5, 9, b'{"a": 1}'),
                   ("edge.Extra", "jsonschema", "json", 6, 0, b'{"a": 2}')]


def test_error_probability_round_trip(tmp_path, profile):
    """/<device>/error: 32FC1 RawImage between depth and confidence, read back bit for bit (NaN
    included) into RecordedOutput.error; a depth map written without one reads back None."""
    path = tmp_path / "err.mcap"
    rng = np.random.default_rng(5)
    err = rng.random((H, W), dtype=np.float32) * np.float32(0.01)
    err[::3, ::2] = np.nan
    with Recorder(path, profile) as rec:
        for s in range(2):
            d, c = _depth(s)
            rec.write_depth(d, c, timestamp_ns=1000 + s, stack=s, sequence=s, error=err if s == 0 else None)
        with pytest.raises(ValueError, match="error float32"):
            rec.write_depth(d, c, timestamp_ns=3000, stack=2, sequence=2, error=err.astype(np.float64))
    outs = list(RecordingReader(path).outputs())
    assert [o.stack for o in outs] == [0, 1]
    assert outs[0].error is not None and outs[0].error.dtype == np.float32
    assert outs[0].error.tobytes() == err.tobytes() and outs[1].error is None
    with open(path, "rb") as f:
        reader = make_reader(f)
        encodings = [RawImage.FromString(m.data).encoding
                     for _, ch, m in reader.iter_messages(topics=[f"/{profile.zenoh.device}/error"])]
    assert encodings == ["32FC1"]

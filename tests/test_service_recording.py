"""Recording and replay: record + replay bit-exact, the committed recording, SIGINT/SIGTERM
finalisation, SIGKILL recovery, bad files."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from _service_helpers import DATA, TEST_PROFILE, interactive_signals, load_test_profile

COMMITTED = DATA / "sim-small.mcap"


def edge(*args, **kw):
    return subprocess.run([sys.executable, "-m", "edge.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=kw.pop("timeout", 300), **kw)


def _small_chunk_profile(tmp_path: Path) -> Path:
    text = TEST_PROFILE.read_text().replace("chunk_size = 4194304", "chunk_size = 65536")
    path = tmp_path / "test-small.toml"
    path.write_text(text)
    return path


def test_service_record_then_replay_bit_exact(tmp_path):
    from edge.io.mcap import RecordingReader
    from edge.io.recording import RecordingThread
    from edge.io.replay import replay_recording
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile(edc={"rounds": 1}, sim={"scene": "v-groove"})
    out = tmp_path / "run.mcap"
    sensor = SimSensor(profile, max_speed=True)
    rec = RecordingThread(out, profile, sensor_metadata=sensor.info.metadata)
    status = Service(profile, sensor, recorder=rec).run(stacks=3)
    assert status["recorder"]["frames_lost"] == 0 and rec.frames_lost == 0
    reader = RecordingReader(out)
    assert reader.complete and reader.profile.name == "test-small"
    outputs = list(reader.outputs())
    assert len(outputs) == 3
    from edge.decode import DEFAULT_SETTINGS

    for o in outputs:  # the library's rule: P(wrong) recorded, below max_error where the decoder's column is published
        assert o.error is not None and np.all(np.isnan(o.error[o.depth_mm == 0]))
        published = ~np.isnan(o.error)
        assert published.mean() > 0.5 and np.all(o.error[published] < DEFAULT_SETTINGS.max_error)
    report = replay_recording(out)
    assert report.ok, report.lines()
    assert report.stacks_compared == 3 and report.stacks_matched == 3
    r = edge("replay", out)
    assert r.returncode == 0 and "bit for bit" in r.stdout, r.stdout + r.stderr


def test_committed_recording_replays_bit_exact():
    if not COMMITTED.exists():
        pytest.skip(f"{COMMITTED} missing")
    assert COMMITTED.stat().st_size < 5 * 1024 * 1024
    r = edge("replay", COMMITTED)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "3 bit-exact" in r.stdout


def test_replay_detects_a_changed_depth(tmp_path):
    from edge.io import replay as replay_mod

    out = tmp_path / "sim.mcap"
    r = edge("sim", "record", out, "--stacks", "2", "--profile", TEST_PROFILE)
    assert r.returncode == 0, r.stderr
    from edge.runtime.pipeline import DepthPipeline

    original = DepthPipeline.process

    def replay_tampered(tamper):
        """Replay `out` with every decoded result passed through tamper(result) first."""
        def process(self, stack, masked_capture=None):
            res = original(self, stack, masked_capture)
            tamper(res)
            return res

        DepthPipeline.process = process
        try:
            return replay_mod.replay_recording(out)
        finally:
            DepthPipeline.process = original

    def flip_depth(res):
        res.depth_mm[0, 0] ^= 1

    report = replay_tampered(flip_depth)
    assert not report.ok and len(report.mismatches) == 2
    assert "depth: 1 of 19200 pixels differ" in report.mismatches[0]

    def nudge_error(res):  # one ulp of one published P(wrong)
        y, x = np.argwhere(res.depth_mm > 0)[0]
        res.error[y, x] = np.nextafter(res.error[y, x], np.float32(1))

    report = replay_tampered(nudge_error)
    assert not report.ok and len(report.mismatches) == 2
    assert "error: 1 of 19200 pixels differ" in report.mismatches[0] and "depth" not in report.mismatches[0]


def test_replay_bad_files(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    r = edge("replay", junk)
    assert r.returncode == 2 and "not an MCAP file" in r.stderr
    r = edge("replay", tmp_path / "missing.mcap")
    assert r.returncode == 2 and "does not exist" in r.stderr
    if COMMITTED.exists():
        r = edge("replay", COMMITTED, "--profile", "sim-dlp")
        assert r.returncode == 2 and "expected 'sim-dlp'" in r.stderr
        cut = tmp_path / "cut.mcap"
        data = COMMITTED.read_bytes()
        cut.write_bytes(data[: len(data) * 2 // 3])
        r = edge("replay", cut)
        assert r.returncode == 2 and "truncated or corrupt" in r.stdout, r.stdout + r.stderr


def _start_recording(tmp_path: Path, out: Path) -> subprocess.Popen:
    profile = _small_chunk_profile(tmp_path)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "edge.cli", "run", "--profile", str(profile), "--no-zenoh",
                             "--record", str(out), "--seconds", "120"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                            preexec_fn=interactive_signals)


def _wait_for_stacks(proc: subprocess.Popen, n: int, timeout: float = 90.0) -> list[str]:
    lines, deadline = [], time.time() + timeout
    while time.time() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if sum(l.startswith("stack ") for l in lines) >= n:
            return lines
    raise AssertionError("service did not produce stacks:\n" + "".join(lines))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_while_recording_finalises_file(tmp_path, sig):
    from edge.io.mcap import RecordingReader
    from edge.sensors.base import stack_schedule

    out = tmp_path / "rec.mcap"
    proc = _start_recording(tmp_path, out)
    _wait_for_stacks(proc, 3)
    proc.send_signal(sig)
    rest, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0, rest
    assert f"stopped by signal {sig.name}" in rest
    reader = RecordingReader(out)
    assert reader.complete  # summary + footer written, CRCs valid
    frames = list(reader.frames())
    seqs = [f.sequence for f in frames]
    assert seqs == list(range(len(seqs)))  # every captured frame up to the signal, none lost
    per_stack = len(stack_schedule(22))
    complete = len(seqs) // per_stack
    assert complete >= 3
    r = edge("replay", out)
    assert r.returncode == 0, r.stdout + r.stderr


def test_sigkill_recover_up_to_last_complete_chunk(tmp_path):
    from edge.io.mcap import RecordingReader

    out = tmp_path / "killed.mcap"
    proc = _start_recording(tmp_path, out)
    _wait_for_stacks(proc, 4)
    proc.kill()
    proc.communicate(timeout=30)
    assert not RecordingReader(out, strict=False).complete
    r = edge("replay", out, "--recover")
    assert "recovered" in r.stdout and "trailing bytes dropped" in r.stdout, r.stdout + r.stderr
    recovered = tmp_path / "killed.recovered.mcap"
    reader = RecordingReader(recovered)
    assert reader.complete
    assert len(list(reader.frames())) >= 24
    assert r.returncode == 0, r.stdout + r.stderr  # what was recovered replays bit-exact


def test_recording_from_before_the_error_rule_replays_with_its_rule():
    """A recorded profile without decoder.validity predates the error-probability rule: it is read
    with the contrast / confidence rule and calibration levels it was decoded with (the previous
    tests/data/sim-small.mcap replays bit for bit so); a profile that states validity is kept."""
    from edge.decode.settings import from_profile
    from edge.io.mcap_reader import recorded_profile_dict
    from edge.profiles import profile_from_dict as build_profile, profile_to_dict

    data = profile_to_dict(load_test_profile())
    for key in ("validity", "levels", "metric", "t_low", "t_high", "spatial_check", "max_error", "backend"):
        del data["decoder"][key]  # the decoder table of the recordings made before those keys
    old = build_profile(recorded_profile_dict(data))
    assert from_profile(old).rule(False) == "confidence" and old.decoder.levels == "calibration"
    assert from_profile(build_profile(data)).rule(False) == "error"  # what it would decode with otherwise
    now = profile_to_dict(load_test_profile())
    assert recorded_profile_dict(now) == now


def test_replay_takes_an_older_recordings_zero_confidence_on_valid_depth():
    """Recordings of format 1 (made before valid pixels got a confidence of at least 1) hold 0
    there; their replay computes 1 and that alone is not a mismatch (any other difference still
    is).  A recording of this format (2, `edge.recording` metadata) gets no such leniency."""
    from types import SimpleNamespace

    from edge.io.mcap import RecordingReader
    from edge.io.replay import ReplayReport, _compare

    depth = np.array([[0, 1500, 1600]], np.uint16)
    out = SimpleNamespace(depth_mm=depth, confidence=np.array([[0, 0, 40]], np.uint8), error=None)
    now = SimpleNamespace(depth_mm=depth, confidence=np.array([[0, 1, 40]], np.uint8), error=None)
    report = ReplayReport("x")
    _compare(report, 0, now, out, None, old_format=True)
    assert report.stacks_matched == 1 and not report.mismatches
    other = SimpleNamespace(depth_mm=depth, confidence=np.array([[1, 0, 40]], np.uint8), error=None)
    _compare(report, 1, other, out, None, old_format=True)  # 1 on invalid depth: a real difference
    assert report.stacks_matched == 1 and len(report.mismatches) == 1
    _compare(report, 2, now, out, None)  # format 2: a valid pixel at 0 is a regression
    assert report.stacks_matched == 1 and len(report.mismatches) == 2
    assert RecordingReader(COMMITTED).format == 1  # the committed recording predates the record


def test_a_recording_cut_before_its_profile_is_named_truncated(tmp_path):
    """A file cut inside its first records (before the profile metadata) was reported as holding
    no edge profile; it is a truncated file."""
    from edge.io.mcap import RecordingError
    from edge.io.replay import replay_recording

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(COMMITTED.read_bytes()[:1000])
    with pytest.raises(RecordingError, match=r"truncated or corrupt MCAP at byte \d+ of 1000.*ends before its profile"):
        replay_recording(cut)


@pytest.mark.parametrize("kind", ["frames", "events"])
def test_replay_compares_every_depth_map_of_a_lagging_service(tmp_path, kind):
    """A decoder far behind its camera: depth maps land in the file dozens of stacks after their
    frames, and the stacks dropped stale never get one.  The recording marks dropped stacks, and
    replay compares every recorded depth map and counts every complete stack without one (it
    gave up on a depth map 16 stacks late, skipped it and still said bit for bit; the stale
    stacks were counted nowhere).  The lag is made, not waited for: each decode waits until the
    camera is `LAG` stacks ahead, more than the queue holds (stale drops) and than 16."""
    import time as _time

    from edge.io.mcap import RecordingReader
    from edge.io.recording import RecordingThread
    from edge.io.replay import replay_recording
    from edge.runtime.pipelines import make_pipeline
    from edge.runtime.service import Service

    lag, queue = 40, 32

    class Counting:
        """The sensor, counting the frames (event slices) read from it."""

        def __init__(self, inner):
            self.inner, self.frames = inner, 0

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def read(self, timeout_s=1.0):
            frame = self.inner.read(timeout_s)
            self.frames += frame is not None
            return frame

    from _service_helpers import small_event_profile
    from edge.sensors import open_sensor

    profile = load_test_profile() if kind == "frames" else small_event_profile()
    sensor = Counting(open_sensor(profile, max_speed=True))

    def lagging(p):
        pipe = make_pipeline(p)
        process = pipe.process

        def later(stack, *a, **k):
            deadline = _time.monotonic() + 10.0
            while sensor.frames < (stack.stack + lag) * sensor.info.frames_per_stack and _time.monotonic() < deadline:
                _time.sleep(0.001)
            return process(stack, *a, **k)

        pipe.process = later
        return pipe

    path = tmp_path / "lag.mcap"
    rec = RecordingThread(path, profile)
    service = Service(profile, sensor, recorder=rec, queue_capacity=queue, pipeline_factory=lagging,
                      warm_variants=False)
    status = service.run(stacks=20)
    rec.close()
    assert RecordingReader(path).format == 2
    from edge.io.event_record import event_stacks

    def stacks(**kw):
        reader = RecordingReader(path)
        return list(reader.stacks(**kw) if kind == "frames" else event_stacks(reader, **kw))

    assert status["stacks_dropped_stale"] > 0 and any(s.dropped == "stale" for s in stacks())
    assert len(stacks(max_pending=16)) > len(stacks())  # depth maps > 16 stacks late
    report = replay_recording(path)
    assert report.ok, report.lines()
    assert report.stacks_compared == report.stacks_matched == status["recorder"]["outputs_written"] == 20
    assert report.stacks_without_output >= status["stacks_dropped_stale"]
    assert report.stacks_read == report.stacks_compared + report.stacks_without_output + report.stacks_incomplete
    # the same file as a sensor (`edge run --sensor replay`) streams its frames in capture order:
    # every complete stack reaches the service (it took the stacks in the order their depth maps
    # completed, and the assembler dropped the earlier ones as out of order)
    from edge.io.replay_sensor import ReplaySensor

    complete = report.stacks_compared + report.stacks_without_output
    again = Service(profile, ReplaySensor(path, max_speed=True), queue_capacity=64, warm_variants=False,
                    pipeline_factory=make_pipeline).run(seconds=60)
    assert again["stacks_complete"] == complete and again["stacks_dropped_incomplete"] == report.stacks_incomplete, again

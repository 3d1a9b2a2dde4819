"""Fault suite, write failures: a full disk while recording.  The service keeps publishing, the status
says recording stopped (with the error and honest counts), the file is finalised in place."""

from __future__ import annotations

import builtins
import errno
import os

import pytest
from mcap.reader import make_reader

import faults_lifecycle as F
from _service_helpers import NumpyPipeline, load_test_profile

_real_open = builtins.open


class FullDisk:
    """A file object that fails with ENOSPC once ``limit`` bytes were written (a partial write first)."""

    def __init__(self, f, limit: int) -> None:
        self.f, self.limit, self.n = f, limit, 0

    def write(self, b):
        b = bytes(b)
        if self.n + len(b) > self.limit:
            k = max(0, self.limit - self.n)
            self.f.write(b[:k])
            self.n += k
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.n += len(b)
        return self.f.write(b)

    def __getattr__(self, name):
        return getattr(self.f, name)


@pytest.fixture
def full_disk(monkeypatch):
    import edge.io.mcap_writer as mw

    def install(limit: int):
        monkeypatch.setattr(mw, "open", lambda p, mode="r", *a, **kw: FullDisk(_real_open(p, mode, *a, **kw), limit)
                            if mode == "wb" else _real_open(p, mode, *a, **kw), raising=False)
    return install


def _count(path):
    with _real_open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        assert reader.get_summary() is not None
        topics = [c.topic for _, c, _ in reader.iter_messages()]
    return topics.count("/test-small/raw"), topics.count("/test-small/depth")


def test_enospc_mid_recording_is_reported_honestly_and_finalised(tmp_path, full_disk):
    """Before the fix: status frames_written 1122 / frames_lost 0 / errors '' while 100 frames reached
    the disk, then an ENOSPC traceback at shutdown and an unfinalised file."""
    from edge.io.recording import RecordingThread
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    full_disk(400_000)
    profile = load_test_profile(recording={"chunk_size": 65536})
    out = tmp_path / "full.mcap"
    sensor = SimSensor(profile, max_speed=True, poses=2)
    rec = RecordingThread(out, profile, sensor_metadata=sensor.info.metadata)
    seen = []
    service = Service(profile, sensor, sinks=[], recorder=rec, pipeline_factory=NumpyPipeline)
    status = service.run(stacks=6, on_tick=lambda s: seen.append(s.status()))
    r = status["recorder"]
    assert status["stacks_decoded"] == 6  # the service kept going after the disk filled up
    assert r["state"] == "stopped" and "No space left on device" in r["error"]
    assert "recording" in status["errors"] and "No space left" in status["errors"]
    raw, depth = _count(out)
    assert r["frames_written"] == raw > 0 and r["outputs_written"] == depth
    assert r["frames_lost"] > 0 and r["frames_written"] + r["frames_lost"] == rec.frames_seen
    assert os.path.getsize(out) <= 400_000
    # while running, a status after the failure already said so
    assert any((s["recorder"] or {}).get("state") == "stopped" for s in seen)


def test_failure_at_finish_still_finalises(tmp_path, full_disk):
    """The last chunk fails to write at close: the file is cut back to its last complete chunk and finalised."""
    from edge.io.mcap_writer import Recorder

    profile = load_test_profile(recording={"chunk_size": 65536})
    import numpy as np

    full_disk(150_000)
    out = tmp_path / "a.mcap"
    rec = Recorder(out, profile)
    img = np.random.default_rng(0).integers(0, 255, (120, 160), dtype=np.uint8)
    n = 0
    try:
        for i in range(200):
            rec.write_raw(img, sequence=i, timestamp_ns=i + 1, stack=i // 24, projector_frame=i % 24)
            n += 1
    except OSError:
        pass
    rec.finish()
    assert rec.error.startswith("No space left on device")
    raw, _ = _count(out)
    assert 0 < raw < n + 1 and rec.finalize_report.topics.get("/test-small/raw") == raw


def test_file_size_limit_in_a_real_edge_run(tmp_path):
    """`edge run --record` with RLIMIT_FSIZE (EFBIG, like a full disk): keeps decoding, one summary,
    the recording finalised, honest counts, no traceback."""
    r = F.full_disk_trial(tmp_path, limit_bytes=600_000, stacks=12)
    assert r["ok"], {k: v for k, v in r.items() if k != "output_tail"} | {"tail": r["output_tail"]}
    assert r["rc"] == 1  # the recording failed: a supervisor sees it

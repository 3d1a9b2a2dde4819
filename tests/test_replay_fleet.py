"""`edge replay DIR --workers 2`: many recordings re-decoded on Ray (local, ``num_cpus=2``), one of
them truncated and one recorded with a tampered depth map; the same files replayed serially give the
same per-file verdicts.  Run alone: ``python -m pytest -q -m fleet``.
"""

from __future__ import annotations

import json
import os
import sys

import pytest

from _service_helpers import load_test_profile

pytestmark = pytest.mark.fleet


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    from edge.commands.sim import record_simulation
    from edge.runtime.pipeline import DepthPipeline

    d = tmp_path_factory.mktemp("recs")
    profile = load_test_profile()
    for i in range(3):
        record_simulation(str(d / f"rec{i}.mcap"), profile, 2, first_stack=2 * i)
    original = DepthPipeline.process

    def tampered(self, stack, masked_capture=None):
        res = original(self, stack, masked_capture)
        res.depth_mm[3, 5] ^= 1
        return res

    DepthPipeline.process = tampered
    try:
        record_simulation(str(d / "tampered.mcap"), profile, 2)
    finally:
        DepthPipeline.process = original
    data = (d / "rec0.mcap").read_bytes()
    (d / "truncated.mcap").write_bytes(data[: len(data) // 2])
    return d


def _verdicts(report):
    return {os.path.basename(f["path"]): (f["identical"], f["stacks_matched"], f["stacks_differ"], bool(f["error"]))
            for f in report["files"]}


EXPECTED = {
    "rec0.mcap": (True, 2, 0, False),
    "rec1.mcap": (True, 2, 0, False),
    "rec2.mcap": (True, 2, 0, False),
    "tampered.mcap": (False, 0, 2, False),
    "truncated.mcap": (False, 0, 0, True),
}


def test_replay_many_serial_and_on_ray(recordings, tmp_path, capsys):
    pytest.importorskip("ray")
    from edge.cli import main

    serial = tmp_path / "serial.json"
    assert main(["replay", str(recordings), "--report", str(serial)]) == 1
    out = capsys.readouterr().out
    assert "5 recordings: 3 bit-identical, 1 differ, 1 failed" in out, out
    report = json.loads(serial.read_text())
    assert report["engine"] == "serial" and not report["all_identical"]
    assert _verdicts(report) == EXPECTED
    assert "truncated" in next(f["error"] for f in report["files"] if f["path"].endswith("truncated.mcap"))

    import signal

    sigterm = signal.getsignal(signal.SIGTERM)
    fleet = tmp_path / "fleet.json"
    assert main(["replay", str(recordings / "*.mcap"), "--workers", "2", "--report", str(fleet)]) == 1
    out = capsys.readouterr().out
    assert "5 recordings: 3 bit-identical, 1 differ, 1 failed" in out and "ray local (2 workers)" in out, out
    report = json.loads(fleet.read_text())
    assert report["engine"] == "ray local" and report["workers"] == 2
    assert _verdicts(report) == EXPECTED
    workers = {f["worker"] for f in report["files"]}
    assert f"{os.uname().nodename}:{os.getpid()}" not in workers  # decoded in Ray worker processes
    import ray

    assert not ray.is_initialized()  # the local instance was shut down
    assert signal.getsignal(signal.SIGTERM) is sigterm  # and ray.init's SIGTERM handler removed


def test_replay_many_all_identical_exits_0(recordings, capsys):
    from edge.cli import main

    assert main(["replay", str(recordings / "rec1.mcap"), str(recordings / "rec2.mcap")]) == 0
    assert "2 recordings: 2 bit-identical, 0 differ, 0 failed" in capsys.readouterr().out


def test_one_file_named_twice_is_replayed_once(recordings, tmp_path, capsys, monkeypatch):
    """The same file as ``rec1.mcap`` and ``./rec1.mcap`` (or through a link) was replayed and counted
    twice; two files of one name in different folders are told apart by their paths."""
    import shutil

    from edge.cli import main

    monkeypatch.chdir(recordings)
    (tmp_path / "link.mcap").symlink_to(recordings / "rec1.mcap")
    assert main(["replay", "rec1.mcap", "./rec1.mcap", str(tmp_path / "link.mcap"), "rec2.mcap"]) == 0
    assert "2 recordings: 2 bit-identical" in capsys.readouterr().out
    other = tmp_path / "again"
    other.mkdir()
    shutil.copy(recordings / "rec1.mcap", other / "rec1.mcap")
    assert main(["replay", "rec1.mcap", str(other / "rec1.mcap")]) == 0
    out = capsys.readouterr().out
    assert "2 recordings: 2 bit-identical" in out and os.path.relpath(other / "rec1.mcap") in out


def test_workers_without_ray_is_one_clear_error(recordings, monkeypatch, capsys):
    from edge.cli import main

    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    assert main(["replay", str(recordings), "--workers", "2"]) == 2
    err = capsys.readouterr().err
    assert "pip install 'edge[fleet]'" in err and "Traceback" not in err
    assert err.count("\n") == 1


def test_replay_many_usage_errors(recordings, tmp_path, capsys):
    from edge.cli import main

    assert main(["replay", str(tmp_path / "none-*.mcap")]) == 2
    assert "matches no file" in capsys.readouterr().err
    assert main(["replay", str(recordings), "--recover"]) == 2
    assert "--recover replays one recording" in capsys.readouterr().err
    assert main(["replay", str(recordings), "--report", str(tmp_path / "no" / "r.json")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["replay", str(tmp_path)]) == 2  # a directory without recordings
    assert "holds no *.mcap" in capsys.readouterr().err


def test_address_nobody_listens_is_one_clear_error(recordings, capsys):
    pytest.importorskip("ray")
    import socket

    from edge.cli import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["replay", str(recordings), "--address", f"127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err
    assert "no Ray cluster answers at 127.0.0.1:" in err and err.count("\n") == 1

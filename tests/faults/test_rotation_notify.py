"""Fault suite, running as an on-device service: record rotation (every file finalised and replayable
on its own), sd_notify (READY / WATCHDOG / STOPPING to a fake NOTIFY_SOCKET), the systemd unit,
warm-up of switchable decoder variants and the stack-budget check of live changes."""

from __future__ import annotations

import configparser
import shlex
import socket
import threading
import time
from pathlib import Path

import pytest

from _service_helpers import NumpyPipeline, load_test_profile

ROOT = Path(__file__).resolve().parents[2]
UNIT = ROOT / "deploy" / "systemd" / "edge.service"


# -- rotation ------------------------------------------------------------------------------------

def test_rotation_by_size_every_file_finalised_and_replayable(tmp_path):
    from mcap.reader import make_reader

    from edge.io.recording import RecordingThread, series_files
    from edge.io.replay import replay_recording
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile(recording={"chunk_size": 65536})
    out = tmp_path / "rot.mcap"
    sensor = SimSensor(profile, poses=2)  # real-time pacing: 200 ms per stack of ~460 kB
    rec = RecordingThread(out, profile, sensor_metadata=sensor.info.metadata, max_bytes=350_000)
    status = Service(profile, sensor, recorder=rec, warm_variants=False).run(stacks=8)
    files = series_files(str(out))
    assert len(files) >= 3 and files == rec.files and not out.exists()
    assert all("-0000.mcap" in files[0] for _ in [0]) and files[1].endswith("-0001.mcap")
    raw_total = 0
    compared = 0
    for i, path in enumerate(files):
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            assert reader.get_summary() is not None
            raw_total += sum(1 for _ in reader.iter_messages(topics=["/test-small/raw"]))
        report = replay_recording(path)
        assert not report.mismatches and not report.problem, report.lines()
        if i < len(files) - 1:  # rotation happens at stack boundaries (the last file may end in a stack cut at stop)
            assert report.stacks_incomplete == 0, report.lines()
        compared += report.stacks_compared
    assert raw_total == status["recorder"]["frames_written"] and status["recorder"]["frames_lost"] == 0
    assert compared >= 6


def test_rotation_keep_bounds_the_number_of_files(tmp_path):
    from edge.io.recording import RecordingThread, series_files
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile(recording={"chunk_size": 65536})
    out = tmp_path / "keep.mcap"
    older = tmp_path / "keep-20000101T000000Z-0000.mcap"   # a series from before a restart
    older.write_bytes(b"old")
    sensor = SimSensor(profile, poses=2)
    rec = RecordingThread(out, profile, max_bytes=200_000, keep=2)
    Service(profile, sensor, recorder=rec, pipeline_factory=NumpyPipeline).run(stacks=6)
    files = series_files(str(out))
    assert len(files) == 2 and not older.exists()


def test_rotation_options_validated(capsys):
    from edge.cli import main

    for args, text in ((["--record-keep", "3"], "need --record"),
                       (["--record", "x.mcap", "--record-keep", "3"], "needs --record-max-mb"),
                       (["--record", "x.mcap", "--record-max-mb", "0"], "--record-max-mb")):
        assert main(["run", "--no-zenoh", *args]) == 2
        assert text in capsys.readouterr().err


# -- sd_notify -----------------------------------------------------------------------------------

class FakeNotifySocket:
    """A unix datagram socket standing in for systemd's NOTIFY_SOCKET."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(path)
        self.sock.settimeout(0.2)
        self.messages: list[str] = []
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._loop, daemon=True)
        self._t.start()

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                self.messages.append(self.sock.recv(4096).decode())
            except socket.timeout:
                continue
            except OSError:
                return

    def close(self) -> None:
        self._stop.set()
        self._t.join(2)
        self.sock.close()


def test_notifier_protocol_and_abstract_socket(tmp_path):
    from edge.runtime.sdnotify import Notifier

    fake = FakeNotifySocket(str(tmp_path / "notify"))
    try:
        n = Notifier(env={"NOTIFY_SOCKET": fake.path, "WATCHDOG_USEC": "400000"})
        assert n.enabled and n.watchdog_usec == 400000
        assert n.ready("up") and n.watchdog() and not n.watchdog()  # rate-limited to a quarter period
        time.sleep(0.11)
        assert n.watchdog() and n.stopping()
        time.sleep(0.3)
    finally:
        fake.close()
    assert fake.messages == ["READY=1\nSTATUS=up", "WATCHDOG=1", "WATCHDOG=1", "STOPPING=1"]
    assert not Notifier(env={}).ready()  # outside systemd: a no-op
    assert Notifier(env={"NOTIFY_SOCKET": fake.path, "WATCHDOG_USEC": "1", "WATCHDOG_PID": "1"}).watchdog_usec is None
    gone = Notifier(env={"NOTIFY_SOCKET": str(tmp_path / "missing")})
    assert not gone.ready() and gone.errors == 1  # never raises
    abstract = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    name = f"edge-test-{time.monotonic_ns()}"
    abstract.bind("\0" + name)
    abstract.settimeout(2)
    try:
        assert Notifier(env={"NOTIFY_SOCKET": "@" + name}).ready()
        assert abstract.recv(100) == b"READY=1"
    finally:
        abstract.close()


def test_service_sends_ready_after_warm_up_watchdog_from_decode_and_stopping(tmp_path):
    from edge.runtime.sdnotify import Notifier
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    fake = FakeNotifySocket(str(tmp_path / "notify"))
    profile = load_test_profile()
    order = []

    class Tracing(NumpyPipeline):
        def warm_up(self):
            order.append(("warm-up", len(fake.messages)))
            return super().warm_up()

    try:
        n = Notifier(env={"NOTIFY_SOCKET": fake.path, "WATCHDOG_USEC": "200000"})
        Service(profile, SimSensor(profile, max_speed=True), notifier=n, pipeline_factory=Tracing).run(stacks=4)
        time.sleep(0.3)
    finally:
        fake.close()
    kinds = [m.split("\n")[0] for m in fake.messages]
    assert "READY=1" in kinds and kinds[-1] == "STOPPING=1" and "WATCHDOG=1" in kinds
    assert order[0][1] == kinds.index("READY=1") or kinds.index("READY=1") >= order[0][1]
    assert kinds.index("READY=1") < kinds.index("STOPPING=1")


def test_edge_run_under_a_fake_systemd(tmp_path, monkeypatch, capsys):
    """The real command: READY=1 once capture runs (after warm-up), STOPPING=1 at the end."""
    import faults_lifecycle as F

    from edge.cli import main

    fake = FakeNotifySocket(str(tmp_path / "notify"))
    monkeypatch.setenv("NOTIFY_SOCKET", fake.path)
    monkeypatch.setenv("WATCHDOG_USEC", "2000000")
    try:
        rc = main(["run", "--profile", str(F.TEST_PROFILE), "--stacks", "3", "--no-zenoh", "--max-speed", "--quiet"])
        time.sleep(0.3)
    finally:
        fake.close()
    assert rc == 0, capsys.readouterr()
    kinds = [m.split("\n")[0] for m in fake.messages]
    assert "READY=1" in kinds and kinds[-1] == "STOPPING=1", kinds
    assert kinds.index("READY=1") < kinds.index("STOPPING=1")


def test_systemd_unit_is_notify_with_watchdog_and_its_command_parses():
    from edge.cli import build_parser

    text = UNIT.read_text().replace("\\\n", " ")
    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.optionxform = str
    cp.read_string(text)
    svc = cp["Service"]
    assert svc["Type"] == "notify" and svc["Restart"] == "on-failure" and int(svc["WatchdogSec"]) > 0
    assert int(svc["TimeoutStartSec"]) >= 300  # a cold kernel compile fits
    argv = shlex.split(svc["ExecStart"])
    assert argv[0].endswith("/edge") and argv[1] == "run"
    args = build_parser().parse_args(argv[1:])
    assert args.record and args.record_max_mb and args.record_keep > 0 and args.quiet
    assert "NUMBA_CACHE_DIR" in svc["Environment"]


# -- warm-up of switchable variants, stack budget -------------------------------------------------

class NoEdc(NumpyPipeline):
    """Numpy decoder; the EDC stage is a sleep proportional to edc.rounds (no numba)."""

    def adaptive(self, stack, images, column, confidence, masked_capture):
        from edge.runtime.edc_stage import EdcOutcome

        rounds = int(self.profile.edc.rounds)
        time.sleep(0.25 * rounds)
        return EdcOutcome(column=column, confidence=confidence, rounds=rounds, extra=[],
                          round_ms=(250.0,) * rounds, capture_ms=(0.0,) * rounds, open_pixels=(0,) * rounds)


def test_switch_to_a_variant_that_failed_to_compile_or_does_not_fit_is_refused():
    from edge.runtime.service import ConfigRejected, Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile()

    class HardBreaks(NoEdc):
        def decode(self, codes, white, black):
            if self.profile.decoder.method == "hard":
                raise RuntimeError("kernel compile failed")
            return super().decode(codes, white, black)

    service = Service(profile, SimSensor(profile, max_speed=True), pipeline_factory=HardBreaks, warm_variants=True)
    assert service.warm_up()
    assert set(service.warm_up_report.seconds) >= {"profile", "decoder.method=list", "decoder.method=median", "edc"}
    with pytest.raises(ConfigRejected, match="hard is unavailable.*kernel compile failed"):
        service.update_config({"decoder": {"method": "hard"}})
    # refused by profile validation (a method per projector kind) or, failing that, by the service
    with pytest.raises(ValueError, match="for a 'columns' projector|does not fit this profile's pipeline"):
        service.update_config({"decoder": {"method": "curtain"}})  # accepted before: then 10 failures, exit 0
    assert service.update_config({"decoder": {"method": "list"}}).decoder.method == "list"
    # and back to the profile's own method (its pipeline is the warm one; it was refused as not
    # fitting the profile, so a method change could only be undone by a restart)
    assert service.update_config({"decoder": {"method": "soft"}}).decoder.method == "soft"
    assert service.update_config({"edc": {"rounds": 1}}).edc.rounds == 1


def test_real_warm_up_covers_every_switchable_variant():
    """The standard pipeline: every other method and the EDC stage decode a synthetic stack."""
    from edge.runtime.pipelines import make_pipeline
    from edge.runtime.warmup import switchable_variants, warm_up_all

    profile = load_test_profile()
    labels = [label for label, _ in switchable_variants(profile)]
    assert labels == ["decoder.method=hard", "decoder.method=list", "decoder.method=median",
                      "decoder.method=list+median", "decoder.method=sgm", "edc"]  # every method of edge.decode.settings.METHODS
    report = warm_up_all(profile, make_pipeline, make_pipeline(profile))
    assert report.done and not report.failed and set(report.seconds) == {"profile", *labels}


def test_live_change_over_the_stack_budget_is_reported():
    """Before the fix edc.rounds = 2 pushed decode to ~500 ms per stack and silently dropped stacks."""
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile()  # 24 frames at 120 fps: a 200 ms stack budget
    logged = []
    service = Service(profile, SimSensor(profile, poses=2), pipeline_factory=NoEdc, log=logged.append)
    changed = []

    def tick(svc):
        if not changed and svc.counters.stacks_decoded >= 2:
            changed.append(svc.update_config({"edc": {"rounds": 2}}))
        if svc.budget:
            svc.stop()

    status = service.run(seconds=60, on_tick=tick)
    b = status["budget"]
    assert b and b["over_budget"] and b["change"] == "edc.rounds" and b["decode_ms_p50"] > b["stack_budget_ms"] == 200.0
    assert status["warnings"] and "over the 200 ms stack budget" in status["warnings"][0]
    assert logged and "warning" in logged[0]
    assert status["edc_rounds"] == 2  # applied (with the warning), not silently reverted


def test_stats_survive_a_file_pruned_while_they_are_taken(tmp_path, monkeypatch):
    """`RecordingThread.stats` runs on the status thread while the writer thread rotates and prunes
    (keep=N): a listed file that is gone by the time it is sized counts 0 bytes (it raised
    FileNotFoundError, which ended the service's run and left the writer thread behind)."""
    from edge.io.recording import RecordingThread

    profile = load_test_profile()
    rec = RecordingThread(tmp_path / "keep.mcap", profile, max_bytes=200_000, keep=2)
    try:
        here = tmp_path / "here.mcap"
        here.write_bytes(b"12345")
        rec.files[:] = [str(tmp_path / "gone.mcap"), str(here)]
        with monkeypatch.context() as m:  # the race: the file still existed when it was listed
            m.setattr("os.path.exists", lambda p: True)
            assert rec.stats()["bytes"] == 5
    finally:
        rec.files[:] = []
        rec.close()

"""Fault suite, service lifecycle: signals at points of the service's life, SIGKILL salvage, the
README subscriber stopping on Ctrl-C, --queue bound and fast stop, exit code on a self-stop.

The long version (>= 20 signal points, cold numba cache) is ``python tools/fault_report.py --full``.
"""

from __future__ import annotations

import json
import re
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import faults_lifecycle as F
from _service_helpers import NumpyPipeline, load_test_profile, slow_pipeline

README = Path(__file__).resolve().parents[2] / "README.md"


@pytest.mark.parametrize("trial", F.CI_TRIALS, ids=lambda t: t.name)
def test_signal_at_a_point_of_the_service_life(trial, tmp_path):
    """Before the fix: SIGTERM during warm-up killed without finalising (handlers came after warm-up),
    SIGINT there hung (zenoh session never closed), SIGHUP left the file unfinalised."""
    r = F.run_signal_trial(trial, tmp_path)
    assert r["reached"], r["output_tail"]
    assert r["ok"], json.dumps({k: v for k, v in r.items() if k != "output_tail"}, default=str) + "\n" + r["output_tail"]
    assert r["exit_s"] < F.EXIT_BOUND_S
    if trial.point in ("steady", "shutdown"):
        assert r["file"]["readable"] and r["file"]["raw"] == r["frames_written"] > 0 and r["frames_lost"] == 0
        assert r["file"]["depth"] >= 3
    if trial.point == "warm-up":  # nothing captured yet: no file at all (an existing one is never touched)
        assert not r["file"]["exists"] and r["rc"] == 0 and r["summary"]


def test_sigkill_leaves_a_file_that_recover_salvages(tmp_path):
    r = F.sigkill_trial(tmp_path)
    assert r["ok"], r
    assert r["salvaged"]["depth"] > 0


def test_readme_subscriber_stops_on_ctrl_c(tmp_path):
    """Before the fix the five-line subscriber ignored Ctrl-C (a non-daemon zenoh thread, no close)."""
    import zenoh

    from edge.io.zenoh import encode_header, make_config

    text = README.read_text()
    block = re.search(r"A subscriber in five lines.*?```python\n(.*?)```", text, re.S).group(1)
    assert len(block.strip().splitlines()) == 5
    port = F.free_port()
    script = tmp_path / "sub.py"
    script.write_text(block.replace("tcp/127.0.0.1:7451", f"tcp/127.0.0.1:{port}"))
    pub_session = zenoh.open(make_config(listen=[f"tcp/127.0.0.1:{port}"]))
    stop = threading.Event()

    def publish():
        pub = pub_session.declare_publisher("sl/sim-dlp/depth")
        seq = 0
        while not stop.is_set():
            d = np.full((4, 6), 1234, dtype="<u2")
            pub.put(d.tobytes(), attachment=encode_header(width=6, height=4, encoding="16UC1", timestamp_ns=1,
                                                          sequence=seq))
            seq += 1
            time.sleep(0.05)
        pub.undeclare()

    t = threading.Thread(target=publish, daemon=True)
    t.start()
    proc = F.Proc([], command=[sys.executable, str(script)])
    try:
        assert proc.wait_for(r"^\d+ 1234$", count=2, timeout=60), proc.output
        proc.signal(signal.SIGINT)
        rc, exit_s = proc.finish(timeout=15)
    finally:
        stop.set()
        t.join(5)
        pub_session.close()
    assert rc == 0 and exit_s < 15 and "Traceback" not in proc.output, proc.output


def test_queue_bound_and_stop_does_not_wait_for_queued_stacks():
    """Before the fix --queue 1000000 was accepted and a stop decoded the whole queue (81 s)."""
    from edge.commands.run import MAX_QUEUE
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    r = F.run_startup_case(["run", "--profile", str(F.TEST_PROFILE), "--no-zenoh", "--queue", "1000000"])
    assert F.startup_error_ok(r, "--queue"), r.stderr
    profile = load_test_profile()
    service = Service(profile, SimSensor(profile, max_speed=True, poses=2),
                      pipeline_factory=slow_pipeline(0.5), queue_capacity=MAX_QUEUE)
    stopped_at = []

    def tick(svc):  # stop once the queue holds many stacks (deterministic, whatever the machine's load)
        if not stopped_at and len(svc.queue) >= 16:
            stopped_at.append(time.monotonic())
            svc.stop()

    status = service.run(seconds=120, on_tick=tick)
    assert stopped_at, "the queue never filled"
    elapsed = time.monotonic() - stopped_at[0]
    assert status["stacks_dropped_at_stop"] >= 15, {k: status[k] for k in ("stacks_complete", "stacks_decoded")}
    assert elapsed < 3.0, elapsed  # at most the stack being decoded (0.5 s), not 16 x 0.5 s


def test_persistent_decode_failure_is_a_fault_with_exit_1(tmp_path, capsys):
    """Before the fix 10 failing stacks in a row stopped the service with exit code 0."""
    from edge.runtime.service import MAX_CONSECUTIVE_DECODE_ERRORS, Service
    from edge.sensors.sim import SimSensor

    class Broken(NumpyPipeline):
        def decode(self, codes, white, black):
            if codes.shape[1] > 8:  # the 8-row warm-up stack passes, every real stack fails
                raise ValueError("decoder exploded")
            return super().decode(codes, white, black)

    profile = load_test_profile()
    status = Service(profile, SimSensor(profile, max_speed=True), pipeline_factory=Broken).run(seconds=60)
    assert status["decode_errors"] >= MAX_CONSECUTIVE_DECODE_ERRORS and "service stopped" in status["fault"]

    from edge.cli import main
    from edge.runtime import service as service_mod

    real = service_mod.Service

    class BrokenService(real):
        def __init__(self, *a, **kw):
            kw["pipeline_factory"] = Broken
            super().__init__(*a, **kw)

    service_mod.Service = BrokenService
    try:
        rc = main(["run", "--profile", str(F.TEST_PROFILE), "--no-zenoh", "--max-speed", "--seconds", "60", "--quiet"])
    finally:
        service_mod.Service = real
    err = capsys.readouterr().err
    assert rc == 1 and "stopped itself" in err, err

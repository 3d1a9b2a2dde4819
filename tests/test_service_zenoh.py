"""End-to-end: `edge run` (sim sensor) publishing over real zenoh on loopback; config updates;
a subscriber that goes away and comes back."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest

from _service_helpers import TEST_PROFILE, NumpyPipeline, load_test_profile

import zenoh  # a hard dependency: a broken install must fail, not skip
from _ports import free_port


def test_edge_run_subprocess_publishes_to_subscriber():
    from edge.io.zenoh import DepthSubscriber

    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "edge.cli", "run", "--profile", str(TEST_PROFILE), "--seconds", "60",
         "--listen", endpoint], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    got = []
    try:
        with DepthSubscriber("test-small", connect=[endpoint]) as sub:
            deadline = time.time() + 90
            while len(got) < 3 and time.time() < deadline and proc.poll() is None:
                s = sub.receive(timeout=1.0)
                if s is not None:
                    got.append(s)
            assert sub.is_alive()
    finally:
        proc.terminate()
        out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0, out
    assert len(got) == 3, out
    s = got[-1]
    assert s.depth_mm.dtype == np.uint16 and s.depth_mm.shape == (120, 160)
    assert s.header["units"] == "mm" and s.header["width"] == 160
    assert np.count_nonzero(s.depth_mm) > 0.5 * s.depth_mm.size
    assert s.confidence is not None and s.confidence.dtype == np.uint8
    # the library's default rule: P(wrong) of every published pixel below max_error, NaN without depth
    from edge.decode import DEFAULT_SETTINGS

    assert s.error is not None and s.error.dtype == np.float32 and s.error.shape == s.depth_mm.shape
    assert np.array_equal(np.isnan(s.error), s.depth_mm == 0)
    assert np.all(s.error[s.depth_mm > 0] < DEFAULT_SETTINGS.max_error)
    assert s.latency_ms > 0
    assert "stopped by signal SIGTERM" in out and "stacks: complete" in out


def _service_with_zenoh(endpoint):
    from edge.profiles import apply_update
    from edge.io.publish import ZenohSink
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = apply_update(load_test_profile(), {"zenoh": {"listen": [endpoint], "status_period_s": 0.2,
                                                          "config_writes": True}})
    service = Service(profile, SimSensor(profile, poses=4), pipeline_factory=NumpyPipeline)
    service.sinks.append(ZenohSink(profile, service))
    return service


def test_config_update_over_zenoh_and_resubscribe():
    import threading

    from edge.io.zenoh import ConfigRejected, DepthSubscriber

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    service = _service_with_zenoh(endpoint)
    runner = threading.Thread(target=service.run, kwargs={"seconds": 60})
    runner.start()
    try:
        with DepthSubscriber("test-small", connect=[endpoint]) as sub:
            assert _receive(sub, 2)
            with pytest.raises(ConfigRejected, match="min_confidence"):
                sub.update_config({"decoder": {"min_confidence": 5.0}})
            with pytest.raises(ConfigRejected, match="camera.width"):
                sub.update_config({"camera": {"width": 64}})
            from edge.decode import DEFAULT_SETTINGS  # the profile does not set it: the library's default

            assert sub.get_config()["decoder"]["min_confidence"] == DEFAULT_SETTINGS.min_confidence
            new = sub.update_config({"decoder": {"min_confidence": 0.25}})
            assert new["decoder"]["min_confidence"] == 0.25
            assert service.profile.decoder.min_confidence == 0.25
            assert _receive(sub, 2)  # still publishing after a rejected and an accepted update
            deadline = time.time() + 5
            while (sub.status is None or "config_rejected" not in sub.status) and time.time() < deadline:
                time.sleep(0.05)
            assert sub.status is not None and sub.status["config_rejected"] >= 2
        # subscriber gone; the service keeps running; a new subscriber gets data again
        time.sleep(0.5)
        assert runner.is_alive()
        with DepthSubscriber("test-small", connect=[endpoint]) as sub2:
            assert _receive(sub2, 2)
    finally:
        service.stop()
        runner.join(30)
    assert not runner.is_alive()
    assert service.counters.sink_errors == 0


def _receive(sub, n, timeout=30.0):
    got, deadline = 0, time.time() + timeout
    while got < n and time.time() < deadline:
        if sub.receive(timeout=0.5) is not None:
            got += 1
    return got == n

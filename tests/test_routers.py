"""Many sensors behind a zenoh router mesh: two in-process routers on loopback (stand-ins for zenohd),
a service connected to router A as a client, subscribers connected to router B; router A restarts.
And `edge subscribe --all` listing two services from one subscriber.

Run alone: ``python -m pytest -q -m routers``.
"""

from __future__ import annotations

import threading
import time

import pytest

from _service_helpers import NumpyPipeline, load_test_profile

import zenoh  # a hard dependency: a broken install fails here, it is not skipped
from _ports import free_port

pytestmark = pytest.mark.routers


def _service(device: str, **zenoh_settings):
    from edge.profiles import apply_update
    from edge.io.publish import ZenohSink
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = apply_update(load_test_profile(), {"zenoh": {"device": device, "status_period_s": 0.2,
                                                           **zenoh_settings}})
    service = Service(profile, SimSensor(profile, poses=4), pipeline_factory=NumpyPipeline)
    service.sinks.append(ZenohSink(profile, service))
    runner = threading.Thread(target=service.run, kwargs={"seconds": 120}, daemon=True)
    runner.start()
    return service, runner


def _stop(*services):
    for service, runner in services:
        service.stop()
    for service, runner in services:
        runner.join(30)
        assert not runner.is_alive()


def _wait(predicate, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def test_service_behind_router_mesh_survives_router_restart():
    from edge.io.zenoh import DepthSubscriber, make_config, open_router

    a, b = f"tcp/127.0.0.1:{free_port()}", f"tcp/127.0.0.1:{free_port()}"
    router_a = open_router([a])
    router_b = open_router([b], connect=[a])  # the mesh: B joins A (and retries A while it is down)
    svc = _service("cam-a", mode="client", listen=[], connect=[a])
    sub_session = zenoh.open(make_config(mode="client", connect=[b]))
    try:
        with DepthSubscriber("cam-a", session=sub_session) as sub:
            # depth published into router A arrives at a subscriber of router B
            first = next((s for s in (sub.receive(timeout=1.0) for _ in range(60)) if s is not None), None)
            assert first is not None, "no depth through the router mesh"
            assert first.depth_mm.shape == (120, 160) and first.confidence is not None
            assert _wait(lambda: sub.status is not None and sub.status["zenoh"]["routers"] == 1, 10)
            assert sub.status["zenoh"]["reconnects"] == 0 and sub.status["zenoh"]["connected"]
            assert sub.is_alive()

            # router A goes away: the service is cut off (its liveliness token disappears behind B)
            router_a.close()
            assert _wait(lambda: not svc[0].sinks[-1].publisher.links.connected, 10)
            assert _wait(lambda: not sub.is_alive(timeout=0.5), 10)
            time.sleep(1.0)
            while sub.receive(timeout=0.1) is not None:  # drain what arrived before the cut
                pass
            gap_start = time.monotonic()
            router_a = open_router([a])  # restarted on the same port: zenoh reconnects by itself

            # the service is back: depth flows again, and its status counts the gap
            def back():
                s = sub.receive(timeout=0.5)
                return s is not None and s.received_ns > 0
            assert _wait(back, 30), "no depth after router A restarted"
            assert sub.is_alive()
            assert _wait(lambda: sub.status is not None and sub.status["zenoh"]["reconnects"] >= 1, 10)
            z = sub.status["zenoh"]
            assert z["connected"] and z["routers"] == 1 and z["disconnects"] == 1 and z["reconnects"] == 1
            assert z["disconnected_s"] >= 1.0  # at least the second we waited with A down
            assert z["disconnected_s"] < 1.0 + (time.monotonic() - gap_start) + 2.0
            assert z["published_while_disconnected"] >= 1
    finally:
        sub_session.close()
        _stop(svc)
        router_b.close()
        router_a.close()
    assert svc[0].counters.sink_errors == 0


def test_subscribe_all_lists_every_device(capsys):
    from edge.cli import main

    a, b = f"tcp/127.0.0.1:{free_port()}", f"tcp/127.0.0.1:{free_port()}"
    from edge.io.zenoh import open_router

    router_a = open_router([a])
    router_b = open_router([b], connect=[a])
    svcs = [_service("cam-1", mode="client", listen=[], connect=[a]),
            # a peer behind a router must be reachable: two peers without listen endpoints on the same
            # router do not get each other's samples (zenoh 1.10 expects peers to connect directly)
            _service("cam-2", mode="peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[b])]
    try:
        assert _wait(lambda: all(s.counters.stacks_published >= 2 for s, _ in svcs), 60)
        rc = main(["subscribe", "--all", "--connect", b, "--seconds", "3", "--interval", "1"])
    finally:
        _stop(*svcs)
        router_b.close()
        router_a.close()
    out = capsys.readouterr().out
    assert rc == 0, out
    last = out.strip().split("sl/* at ")[-1].splitlines()
    assert last[0].endswith("(2 devices, 2 alive)"), out
    rows = {line.split()[0]: line.split() for line in last[3:]}
    assert set(rows) == {"cam-1", "cam-2"}, out
    for cols in rows.values():
        assert cols[1] == "yes"
        assert float(cols[2]) > 0  # depth maps/s measured at the subscriber
        assert float(cols[3]) > 0  # latency p50 measured at the subscriber
        assert int(cols[5]) >= 2   # maps received
        assert cols[7] != "-"      # the service's own fps from its status


def test_subscribe_all_without_devices_exits_1(capsys):
    from edge.cli import main

    rc = main(["subscribe", "--all", "--connect", f"tcp/127.0.0.1:{free_port()}", "--seconds", "0.5",
               "--interval", "0.5"])
    assert rc == 1
    assert "no device under sl/" in capsys.readouterr().out


def test_run_mode_client_needs_a_router():
    import argparse

    from edge.commands.run import load_run_profile
    from edge.profiles import ProfileError

    args = argparse.Namespace(profile="sim-dlp", listen=None, connect=["tcp/127.0.0.1:7"], mode="client")
    p = load_run_profile(args)
    assert p.zenoh.mode == "client" and p.zenoh.listen == () and p.zenoh.connect == ("tcp/127.0.0.1:7",)
    with pytest.raises(ProfileError, match="zenoh.connect"):
        load_run_profile(argparse.Namespace(profile="sim-dlp", listen=None, connect=None, mode="client"))


def test_client_waits_for_its_router_with_connect_timeout():
    from edge.io.zenoh import DepthPublisher, open_router
    from edge.profiles import apply_update

    a = f"tcp/127.0.0.1:{free_port()}"
    client = {"zenoh": {"mode": "client", "listen": [], "connect": [a]}}
    with pytest.raises(zenoh.ZError):  # zenoh's client default: fail at once when no router answers
        DepthPublisher(apply_update(load_test_profile(), client))
    routers = []
    timer = threading.Timer(1.0, lambda: routers.append(open_router([a])))
    timer.start()
    try:
        start = time.monotonic()
        profile = apply_update(load_test_profile(), {"zenoh": {**client["zenoh"], "connect_timeout_s": 20}})
        with DepthPublisher(profile) as pub:  # zenoh.open waits for the router (connect/timeout_ms)
            assert time.monotonic() - start >= 0.9
            assert pub.links.stats()["routers"] == 1 and pub.links.connected
    finally:
        timer.join()
        for r in routers:
            r.close()


def test_router_links_count_gaps_exactly():
    """RouterLinks arithmetic on scripted transport events and a fake clock."""
    from types import SimpleNamespace

    from edge.io.zenoh_links import RouterLinks

    now = [100.0]
    listeners = []
    info = SimpleNamespace(declare_transport_events_listener=lambda cb, history: listeners.append(cb)
                           or SimpleNamespace(undeclare=lambda: None))
    links = RouterLinks(SimpleNamespace(info=info), expect_router=True, clock=lambda: now[0])
    (emit,) = listeners

    def event(opened, zid, kind=zenoh.WhatAmI.ROUTER):
        emit(SimpleNamespace(kind=zenoh.SampleKind.PUT if opened else zenoh.SampleKind.DELETE,
                             transport=SimpleNamespace(zid=zid, whatami=kind)))

    now[0] = 102.0
    event(True, "r1")                       # first router after 2 s: a start-up gap, not a reconnect
    event(True, "p1", zenoh.WhatAmI.PEER)
    assert links.stats() == {"routers": 1, "peers": 1, "connected": True, "disconnects": 0, "reconnects": 0,
                             "disconnected_s": 2.0, "published_while_disconnected": 0}
    now[0] = 110.0
    event(False, "r1")                      # cut off at 110
    links.count_publish()
    links.count_publish()
    now[0] = 113.5
    assert links.stats()["disconnected_s"] == 5.5 and not links.stats()["connected"]
    event(True, "r2")                       # back at 113.5 through another router
    event(True, "r1")
    event(False, "r1")                      # one of two routers gone: still connected
    now[0] = 120.0
    s = links.stats()
    assert (s["routers"], s["disconnects"], s["reconnects"], s["disconnected_s"]) == (1, 1, 1, 5.5)
    assert s["published_while_disconnected"] == 2 and s["connected"]


def test_edge_router_command_routes_and_reports():
    # a subprocess, as deployed (one process per router)
    import os
    import subprocess
    import sys

    from edge.io.zenoh import make_config

    a = f"tcp/127.0.0.1:{free_port()}"
    proc = subprocess.Popen([sys.executable, "-m", "edge.cli", "router", "--listen", a, "--seconds", "30"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert "listening on " + a in proc.stdout.readline()
        session = zenoh.open(make_config(mode="client", connect=[a]))
        assert len(session.info.routers_zid()) == 1
        line = proc.stdout.readline()
        session.close()
        assert " client " in line and line.rstrip().endswith("connected"), line
    finally:
        proc.terminate()
        out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out

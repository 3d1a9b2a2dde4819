"""zenoh key space with real sessions on loopback (multicast scouting off)."""

from __future__ import annotations

import json
import socket
import threading
import time

import cv2
import numpy as np
import pytest
import zenoh

from edge.cli import main as cli_main
from edge.io.zenoh import ConfigRejected, DepthPublisher, DepthSubscriber, make_config
from edge.profiles import ProfileError, apply_update, load_profile, profile_to_dict

H, W = 48, 64


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture()
def endpoint():
    return f"tcp/127.0.0.1:{_free_port()}"


@pytest.fixture()
def publisher(endpoint):
    profile = apply_update(load_profile("sim-dlp"), {"zenoh": {"listen": [endpoint], "config_writes": True}})
    pub = DepthPublisher(profile)
    yield pub
    pub.close()


def _wait_until_matched(publisher, timeout: float = 10.0) -> None:
    """Until the subscriber's declarations (depth, error, confidence, status) have reached the
    publisher: each of its zenoh publishers has a matching subscriber (a fixed sleep here could
    lose the first samples on a loaded machine).  A second subscriber on one of those keys in the
    subscriber's session then needs no declaration of its own to get the samples."""
    pubs = [publisher._depth, publisher._error, publisher._confidence, publisher._status]
    deadline = time.monotonic() + timeout
    while not all(p.matching_status.matching for p in pubs):
        assert time.monotonic() < deadline, "the subscriber's declarations never reached the publisher"
        time.sleep(0.01)


@pytest.fixture()
def subscriber(publisher, endpoint):
    sub = DepthSubscriber(publisher.profile.zenoh.device, connect=[endpoint])
    deadline = time.monotonic() + 5
    while not sub.is_alive(timeout=0.5):  # wait until the sessions see each other
        assert time.monotonic() < deadline, "subscriber never saw the publisher"
    _wait_until_matched(publisher)
    yield sub
    sub.close()


def _depth(i: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(i)
    return rng.integers(0, 65536, (H, W), dtype=np.uint16), rng.integers(0, 256, (H, W), dtype=np.uint8)


def test_depth_round_trip_is_bit_exact(publisher, subscriber):
    for i in range(4):
        d, c = _depth(i)
        publisher.publish_depth(d, c, timestamp_ns=time.time_ns(), sequence=i, stack=10 + i)
        time.sleep(0.01)
    for i in range(4):
        sample = subscriber.receive(timeout=3.0)
        assert sample is not None, f"depth {i} did not arrive"
        d, c = _depth(i)
        assert sample.header["sequence"] == i and sample.header["stack"] == 10 + i
        assert (sample.header["width"], sample.header["height"], sample.header["units"]) == (W, H, "mm")
        assert sample.depth_mm.dtype == np.uint16 and np.array_equal(sample.depth_mm, d)
        assert sample.confidence is not None and np.array_equal(sample.confidence, c)
        assert 0 <= sample.latency_ms < 5000
    assert subscriber.errors == []


def test_status_and_wire_format(publisher, subscriber, endpoint):
    raw = []
    session = subscriber.session
    sub = session.declare_subscriber("sl/sim-dlp/depth", lambda s: raw.append(
        (s.payload.to_bytes(), s.attachment.to_bytes(), str(s.encoding))))
    try:
        d, c = _depth(7)
        publisher.publish_depth(d, c, timestamp_ns=123, sequence=7)
        publisher.publish_status({"fps": 5.0, "stacks_dropped": 0, "decoder": "soft"})
        deadline = time.monotonic() + 3
        while (not raw or subscriber.status is None) and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        sub.undeclare()
    assert raw and subscriber.status is not None, "no depth or status arrived"
    payload, attachment, encoding = raw[0]
    assert payload == d.astype("<u2").tobytes()  # little-endian 16UC1, row-major
    header = json.loads(attachment)
    assert header["encoding"] == "16UC1" and header["timestamp_ns"] == 123 and header["v"] == 1
    assert "16UC1" in encoding
    assert subscriber.status["fps"] == 5.0 and subscriber.status["device"] == "sim-dlp"


def test_config_query_and_updates(publisher, subscriber):
    assert subscriber.get_config() == profile_to_dict(publisher.profile)
    new = subscriber.update_config({"decoder": {"method": "hard"}, "edc": {"rounds": 2}})
    assert new["decoder"]["method"] == "hard" and publisher.profile.edc.rounds == 2
    before = publisher.profile
    bad = [
        (b"{not json", "payload is not valid JSON"),
        ({"decoder": {"methd": "hard"}}, "decoder.methd: unknown key"),
        ({"edc": {"rounds": "two"}}, "edc.rounds: expected an integer, got string"),
        ({"camera": {"bits": 9}}, "camera.bits: expected one of"),
        (b"[1, 2]", "expected a JSON object of settings, got list"),
        ({"zenoh": {"listen": []}}, "zenoh cannot change while running"),
    ]
    for update, reason in bad:
        with pytest.raises(ConfigRejected, match="^config update rejected: .*" + reason.replace(".", r"\.")):
            subscriber.update_config(update)
        assert publisher.profile is before  # old config kept
    assert subscriber.get_config()["decoder"]["method"] == "hard"
    # parameters form of an update
    replies = list(subscriber.session.get("sl/sim-dlp/config?edc.rounds=3;decoder.method=list", timeout=2.0))
    assert replies[0].ok is not None and publisher.profile.edc.rounds == 3
    assert publisher.profile.decoder.method == "list"


def test_on_update_callback_decides(endpoint):
    calls = []

    def on_update(partial):
        calls.append(partial)
        if partial.get("edc", {}).get("rounds", 0) > 4:
            raise ValueError("edc.rounds above 4 would drop stacks at 120 fps")
        return apply_update(pub.profile, partial)

    profile = apply_update(load_profile("sim-dlp"), {"zenoh": {"listen": [endpoint], "config_writes": True}})
    pub = DepthPublisher(profile, on_update=on_update)
    try:
        with DepthSubscriber("sim-dlp", connect=[endpoint]) as sub:
            with pytest.raises(ConfigRejected, match="would drop stacks"):
                sub.update_config({"edc": {"rounds": 6}})
            assert pub.profile.edc.rounds == 0
            assert sub.update_config({"edc": {"rounds": 1}})["edc"]["rounds"] == 1
            assert calls == [{"edc": {"rounds": 6}}, {"edc": {"rounds": 1}}]
    finally:
        pub.close()


def test_liveliness_token_appears_and_goes(endpoint):
    profile = apply_update(load_profile("sim-dlp"), {"zenoh": {"listen": [endpoint]}})
    watcher = zenoh.open(make_config(connect=[endpoint]))
    events = []
    seen = threading.Event()

    def on(sample):
        events.append(sample.kind)
        seen.set()

    try:
        pub = DepthPublisher(profile)
        sub = watcher.liveliness().declare_subscriber("sl/sim-dlp/alive", on, history=True)
        try:
            assert seen.wait(5.0) and events[0] == zenoh.SampleKind.PUT
            seen.clear()
            pub.close()
            assert seen.wait(5.0) and events[-1] == zenoh.SampleKind.DELETE
        finally:
            sub.undeclare()
            pub.close()
    finally:
        watcher.close()


def test_publisher_rejects_bad_arrays(publisher):
    with pytest.raises(ValueError, match=r"expected depth as \(H, W\) uint16"):
        publisher.publish_depth(np.zeros((4, 4), np.float32), None, timestamp_ns=0, sequence=0)
    with pytest.raises(ValueError, match="expected confidence"):
        publisher.publish_depth(np.zeros((4, 4), np.uint16), np.zeros((4, 5), np.uint8), timestamp_ns=0, sequence=0)
    with pytest.raises(ProfileError):
        apply_update(publisher.profile, {"zenoh": {"mode": "client", "connect": []}})


def test_cli_subscribe_writes_png(publisher, endpoint, tmp_path, capsys):
    stop = threading.Event()

    def feed():
        i = 0
        y, x = np.mgrid[0:H, 0:W]
        while not stop.is_set():
            d = (500 + 10 * x + y).astype(np.uint16)
            d[:4] = 0
            publisher.publish_depth(d, np.full((H, W), 200, np.uint8), timestamp_ns=time.time_ns(), sequence=i)
            i += 1
            time.sleep(0.02)

    thread = threading.Thread(target=feed, daemon=True)
    thread.start()
    png = tmp_path / "depth.png"
    try:
        rc = cli_main(["subscribe", "--connect", endpoint, "--count", "5", "--seconds", "10", "--png", str(png)])
    finally:
        stop.set()
        thread.join(5)
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "received 5 depth maps" in out and "latency ms p50" in out
    img = cv2.imread(str(png))
    assert img.shape == (H, W, 3) and (img[:4] == 0).all() and img[10:].max() > 0


def test_cli_subscribe_without_service_fails_cleanly(capsys):
    rc = cli_main(["subscribe", "--connect", f"tcp/127.0.0.1:{_free_port()}", "--seconds", "0.5"])
    assert rc == 1 and "no depth from sl/sim-dlp" in capsys.readouterr().out


def _error(i: int) -> np.ndarray:
    rng = np.random.default_rng(100 + i)
    e = rng.random((H, W), dtype=np.float32) * np.float32(0.02)
    e[rng.random((H, W)) < 0.3] = np.nan  # no depth there
    return e


def test_error_probability_round_trip_is_bit_exact(publisher, subscriber):
    """sl/<device>/error: 32FC1 little-endian, NaN kept, paired with its depth by sequence; a
    depth map published without one arrives with error None."""
    raw = []
    sub = subscriber.session.declare_subscriber("sl/sim-dlp/error", lambda s: raw.append(
        (json.loads(s.attachment.to_bytes()), str(s.encoding))))
    try:
        for i in range(4):
            d, c = _depth(i)
            publisher.publish_depth(d, c, timestamp_ns=time.time_ns(), sequence=i, stack=i,
                                    error=_error(i) if i % 2 == 0 else None)
            time.sleep(0.01)
        for i in range(4):
            sample = subscriber.receive(timeout=3.0)
            assert sample is not None and sample.header["sequence"] == i
            assert sample.header.get("error") == (True if i % 2 == 0 else None)  # the subscriber waits for it
            if i % 2 == 0:
                assert sample.error is not None and sample.error.dtype == np.float32
                assert sample.error.tobytes() == _error(i).tobytes()
            else:
                assert sample.error is None
        deadline = time.monotonic() + 3
        while len(raw) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        sub.undeclare()
    assert [h["sequence"] for h, _ in raw] == [0, 2]
    assert all(h["encoding"] == "32FC1" and h["units"] == "probability" and "32FC1" in enc for h, enc in raw)
    with pytest.raises(ValueError, match="error"):
        publisher.publish_depth(*_depth(0), timestamp_ns=0, sequence=9, error=np.zeros((H, W), np.float64))
    assert subscriber.errors == []

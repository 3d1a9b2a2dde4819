"""Foxglove live sink: a plain WebSocket client speaking the Foxglove WebSocket protocol
(subprotocol ``foxglove.websocket.v1``; foxglove-sdk >= 0.30 answers with its successor name
``foxglove.sdk.v1``, same messages) sees the advertised channels and decodes messages with
the independent foxglove protobuf schemas."""

from __future__ import annotations

import json
import struct
import threading
import time

import numpy as np
import pytest

from _service_helpers import NumpyPipeline, load_test_profile

import foxglove  # noqa: E402,F401  (test extra: foxglove-sdk)
import websockets.sync.client as ws_client  # noqa: E402  (test extra)


def _recv_until(ws, pred, timeout=60.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        try:
            msg = ws.recv(timeout=max(0.1, deadline - time.time()))
        except TimeoutError:
            break
        if pred(msg):
            return msg
    raise AssertionError("expected message did not arrive")


def test_foxglove_sink_advertises_channels_and_streams_depth_and_points():
    from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

    from edge.io.foxglove_sink import FoxgloveSink
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile()
    sink = FoxgloveSink(profile, port=0)
    service = Service(profile, SimSensor(profile, poses=2), sinks=[sink], pipeline_factory=NumpyPipeline)
    runner = threading.Thread(target=service.run, kwargs={"seconds": 60})
    try:
        with ws_client.connect(f"ws://127.0.0.1:{sink.port}", subprotocols=["foxglove.websocket.v1", "foxglove.sdk.v1"],
                               open_timeout=10) as ws:
            assert ws.subprotocol in ("foxglove.websocket.v1", "foxglove.sdk.v1")
            adv = json.loads(_recv_until(ws, lambda m: isinstance(m, str) and '"advertise"' in m))
            channels = {c["topic"]: c for c in adv["channels"]}
            assert {"/test-small/depth": "foxglove.RawImage", "/test-small/confidence": "foxglove.RawImage",
                    "/test-small/error": "foxglove.RawImage",
                    "/test-small/points": "foxglove.PointCloud",
                    "/test-small/calibration": "foxglove.CameraCalibration",
                    "/test-small/tf": "foxglove.FrameTransforms"}.items() <= \
                {t: c["schemaName"] for t, c in channels.items()}.items()
            wanted = ["depth", "points", "calibration", "tf"]
            subs = [{"id": i, "channelId": channels[f"/test-small/{leaf}"]["id"]} for i, leaf in enumerate(wanted)]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            runner.start()
            got: dict[str, bytes] = {}
            deadline = time.time() + 60
            while len(got) < len(wanted) and time.time() < deadline:
                msg = _recv_until(ws, lambda m: isinstance(m, bytes) and m[0] == 1, timeout=deadline - time.time())
                sub_id, _log_time = struct.unpack_from("<IQ", msg, 1)
                got.setdefault(wanted[sub_id], msg[13:])
    finally:
        service.stop()
        if runner.is_alive():
            runner.join(60)
        sink.close()
    assert set(got) == set(wanted)
    for leaf in wanted:
        assert channels[f"/test-small/{leaf}"]["encoding"] == "protobuf"
    depth = RawImage()
    depth.ParseFromString(got["depth"])
    assert (depth.width, depth.height, depth.encoding, depth.frame_id) == (160, 120, "16UC1", "test_small_optical_frame")
    assert np.count_nonzero(np.frombuffer(depth.data, "<u2")) > 0.5 * 160 * 120
    cloud = PointCloud()
    cloud.ParseFromString(got["points"])
    xyz = np.frombuffer(cloud.data, "<f4").reshape(-1, 3)
    assert cloud.frame_id == "test_small_optical_frame" and cloud.point_stride == 12 and len(xyz) > 500
    assert np.all(xyz[:, 2] > 0)
    calib = CameraCalibration()
    calib.ParseFromString(got["calibration"])
    assert calib.frame_id == depth.frame_id and calib.K[0] == profile.geometry.focal_px
    tf = FrameTransforms()
    tf.ParseFromString(got["tf"])
    pairs = {(t.parent_frame_id, t.child_frame_id) for t in tf.transforms}
    assert pairs == {("test_small_link", "test_small_optical_frame"),
                     ("test_small_optical_frame", "test_small_projector_optical_frame")}


def test_layout_file_names_the_recording_topics():
    from pathlib import Path

    layout = json.loads((Path(__file__).parents[1] / "docs" / "foxglove" / "edge-layout.json").read_text())
    text = json.dumps(layout)
    for leaf in ("depth", "confidence", "points", "calibration"):
        assert f"/sim-dlp/{leaf}" in text
    assert "sim_dlp_optical_frame" in text or "sim_dlp_link" in text


def test_edge_run_names_the_port_it_bound(capsys):
    """``--foxglove 0`` binds any free port; the banner printed ws://127.0.0.1:0."""
    from _service_helpers import TEST_PROFILE
    from edge.cli import main

    assert main(["run", "--profile", str(TEST_PROFILE), "--foxglove", "0", "--no-zenoh", "--stacks", "1",
                 "--max-speed", "--quiet"]) == 0
    banner = [line for line in capsys.readouterr().out.splitlines() if "Foxglove ws://" in line]
    port = int(banner[0].split("Foxglove ws://127.0.0.1:")[1].split(",")[0].split()[0])
    assert port > 0


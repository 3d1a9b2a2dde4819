"""ROS 2 over rmw_zenoh: what edge publishes, checked with independent parts.

* type hashes against rosbags' REP 2016 implementation and the published hash of
  sensor_msgs/msg/Image (rmw_zenoh's design document / a Jazzy install);
* CDR payloads decoded by rosbags' deserialiser (not edge's code);
* key expressions and liveliness tokens spelled out from rmw_zenoh's design document, seen by a
  plain zenoh client through an in-process zenoh router (standing in for rmw_zenohd);
* `edge run --ros` connects to the router instead of listening on 7447.
"""

from __future__ import annotations

import struct
import threading
import time

import numpy as np
import pytest

from _service_helpers import NumpyPipeline, load_test_profile

import rosbags.typesys as rosbags_typesys  # noqa: E402  (test extra)
import zenoh  # noqa: E402
from _ports import free_port

IMAGE_HASH = "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47"
TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo", "sensor_msgs/msg/PointCloud2", "tf2_msgs/msg/TFMessage")


def _store():
    return rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_JAZZY)


def _conf(mode, listen=(), connect=()):
    import json

    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("listen/endpoints", json.dumps(list(listen)))
    c.insert_json5("connect/endpoints", json.dumps(list(connect)))
    c.insert_json5("scouting/multicast/enabled", "false")
    return c


def test_type_hashes_match_rosbags_and_the_published_image_hash():
    from edge.io.ros import type_hash

    store = _store()
    for t in TYPES:
        assert type_hash(t) == store.hash_rihs01(t), t
    assert type_hash("sensor_msgs/msg/Image") == IMAGE_HASH


def test_cdr_matches_rosbags_bytes_and_decodes():
    from edge.io import ros

    store = _store()
    depth = (np.arange(12, dtype=np.uint16) * 300).reshape(3, 4)
    msg = ros.image_message(depth, timestamp_ns=1_700_000_000_123_456_789, frame_id="cam_optical_frame")
    data = ros.serialize_cdr("sensor_msgs/msg/Image", msg)
    assert data[:4] == b"\x00\x01\x00\x00"  # CDR little endian encapsulation
    img = store.deserialize_cdr(data, "sensor_msgs/msg/Image")
    assert (img.header.stamp.sec, img.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    assert img.encoding == "16UC1" and img.step == 8 and img.is_bigendian == 0
    assert np.array_equal(img.data.view("<u2").reshape(3, 4), depth)
    # byte-identical to rosbags' own serialiser
    assert store.serialize_cdr(img, "sensor_msgs/msg/Image") == data
    err = np.array([[0.0, 1e-6, np.nan], [0.25, np.nan, 1.0]], dtype=np.float32)  # NaN = no estimate
    data = ros.serialize_cdr("sensor_msgs/msg/Image", ros.image_message(err, timestamp_ns=5, frame_id="f"))
    img = store.deserialize_cdr(data, "sensor_msgs/msg/Image")
    assert (img.height, img.width, img.encoding, img.step, img.is_bigendian) == (2, 3, "32FC1", 12, 0)
    assert np.array_equal(img.data.view("<f4").reshape(2, 3), err, equal_nan=True)
    assert store.serialize_cdr(img, "sensor_msgs/msg/Image") == data
    with pytest.raises(ValueError, match="float32"):
        ros.image_message(err.astype(np.float64), timestamp_ns=5, frame_id="f")
    k = [500.0, 0, 320, 0, 500, 240, 0, 0, 1]
    info = ros.camera_info_message(k, 640, 480, timestamp_ns=5, frame_id="f")
    data = ros.serialize_cdr("sensor_msgs/msg/CameraInfo", info)
    ci = store.deserialize_cdr(data, "sensor_msgs/msg/CameraInfo")
    assert store.serialize_cdr(ci, "sensor_msgs/msg/CameraInfo") == data
    assert list(ci.k) == k and list(ci.p) == [500, 0, 320, 0, 0, 500, 240, 0, 0, 0, 1, 0]
    pts = np.random.default_rng(0).normal(size=(7, 3)).astype(np.float32)
    data = ros.serialize_cdr("sensor_msgs/msg/PointCloud2", ros.point_cloud2_message(pts, timestamp_ns=5, frame_id="f"))
    pc = store.deserialize_cdr(data, "sensor_msgs/msg/PointCloud2")
    assert store.serialize_cdr(pc, "sensor_msgs/msg/PointCloud2") == data
    assert [(f.name, f.offset, f.datatype, f.count) for f in pc.fields] == [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1)]
    assert np.array_equal(pc.data.view("<f4").reshape(-1, 3), pts)
    data = ros.serialize_cdr("tf2_msgs/msg/TFMessage", ros.tf_message("sim-dlp", 0.08, timestamp_ns=7))
    tf = store.deserialize_cdr(data, "tf2_msgs/msg/TFMessage")
    assert store.serialize_cdr(tf, "tf2_msgs/msg/TFMessage") == data and len(tf.transforms) == 2


def test_ros_names_and_domain():
    from edge.io.ros import domain_id_from_env, frame_ids, ros_name

    assert ros_name("sim-dlp") == "sim_dlp" and ros_name("3d-cam") == "_3d_cam"
    assert frame_ids("oak-d-pro")["optical"] == "oak_d_pro_optical_frame"
    assert domain_id_from_env({}) == 0 and domain_id_from_env({"ROS_DOMAIN_ID": "7"}) == 7
    with pytest.raises(ValueError, match="ROS_DOMAIN_ID"):
        domain_id_from_env({"ROS_DOMAIN_ID": "x"})


class ErrorPipeline(NumpyPipeline):
    """NumpyPipeline whose decoder also estimates P(wrong column) (as the "error" rule's does)."""

    def decode(self, codes, white, black):
        d = super().decode(codes, white, black)
        d.error = (0.5 * (1.0 - d.confidence)).astype(np.float32)
        return d


class Collect:
    def __init__(self):
        self.results = []

    def on_result(self, r):
        self.results.append(r)

    def on_status(self, status):
        pass

    def close(self):
        pass


def test_service_publishes_ros2_topics_through_a_router():
    """A service in ROS mode, an in-process zenoh router (rmw_zenohd's role) and a plain zenoh
    client: the client lists the liveliness tokens and decodes one sample of every topic (the
    error image against the service's own result)."""
    from edge.profiles import apply_update
    from edge.io.publish import ZenohSink
    from edge.io.ros_sink import RosSink
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    store = _store()
    router_ep = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(_conf("router", listen=[router_ep]))
    client = zenoh.open(_conf("client", connect=[router_ep]))
    try:
        profile = apply_update(load_test_profile(), {
            "zenoh": {"listen": [f"tcp/127.0.0.1:{free_port()}"], "connect": [router_ep]},
            "ros": {"enabled": True, "router": router_ep}})
        # keys spelled out from rmw_zenoh's design document (domain 3 from ROS_DOMAIN_ID)
        image_t = f"sensor_msgs::msg::dds_::Image_/{IMAGE_HASH}"
        info_t = f"sensor_msgs::msg::dds_::CameraInfo_/{store.hash_rihs01('sensor_msgs/msg/CameraInfo')}"
        cloud_t = f"sensor_msgs::msg::dds_::PointCloud2_/{store.hash_rihs01('sensor_msgs/msg/PointCloud2')}"
        tf_t = f"tf2_msgs::msg::dds_::TFMessage_/{store.hash_rihs01('tf2_msgs/msg/TFMessage')}"
        keys = {"depth": f"3/test_small/depth/image_rect_raw/{image_t}", "tf": f"3/tf/{tf_t}",
                "depth_info": f"3/test_small/depth/camera_info/{info_t}",
                "error": f"3/test_small/error/image_rect_raw/{image_t}",
                "error_info": f"3/test_small/error/camera_info/{info_t}",
                "confidence": f"3/test_small/confidence/image_rect_raw/{image_t}",
                "confidence_info": f"3/test_small/confidence/camera_info/{info_t}",
                "points": f"3/test_small/depth/points/{cloud_t}"}
        got: dict[str, list] = {k: [] for k in keys}
        lock = threading.Lock()

        def on(leaf):
            def cb(sample):
                with lock:
                    got[leaf].append((sample.payload.to_bytes(), sample.attachment.to_bytes()))
            return cb

        subs = [client.declare_subscriber(key, on(leaf)) for leaf, key in keys.items()]
        service = Service(profile, SimSensor(profile, poses=2), pipeline_factory=ErrorPipeline)
        zsink = ZenohSink(profile, service)
        rsink = RosSink(profile, session=zsink.publisher.session, environ={"ROS_DOMAIN_ID": "3"})
        collect = Collect()
        service.sinks.extend([collect, rsink, zsink])
        runner = threading.Thread(target=service.run, kwargs={"seconds": 60})
        runner.start()
        try:
            deadline = time.time() + 60
            while time.time() < deadline and not all(len(v) >= 2 for v in got.values()):
                time.sleep(0.1)
            tokens = sorted(str(r.ok.key_expr) for r in client.liveliness().get("@ros2_lv/3/**", timeout=5)
                            if r.ok is not None)
        finally:
            service.stop()
            runner.join(60)
            for s in subs:
                s.undeclare()
        assert all(len(v) >= 2 for v in got.values()), {k: len(v) for k, v in got.items()}
        zid = str(zsink.publisher.session.info.zid())
        qos = "::,10:,:,:,,"
        assert f"@ros2_lv/3/{zid}/0/0/NN/%/%/test_small" in tokens, tokens
        pubs = [t for t in tokens if "/MP/" in t]
        assert len(pubs) == 8
        assert any(t.endswith(f"/MP/%/%/test_small/%tf/{tf_t}/{qos}") for t in pubs), pubs
        for topic, typ in [("depth/image_rect_raw", image_t), ("depth/camera_info", info_t),
                           ("error/image_rect_raw", image_t), ("error/camera_info", info_t),
                           ("confidence/image_rect_raw", image_t), ("confidence/camera_info", info_t),
                           ("depth/points", cloud_t)]:
            mangled = "%test_small%" + topic.replace("/", "%")
            assert any(t.startswith(f"@ros2_lv/3/{zid}/0/") and t.endswith(f"/MP/%/%/test_small/{mangled}/{typ}/{qos}")
                       for t in pubs), (topic, pubs)
        # decode with rosbags; attachments: int64 seq, int64 ns, 16, GID
        payload, att = got["depth"][-1]
        img = store.deserialize_cdr(payload, "sensor_msgs/msg/Image")
        assert (img.height, img.width, img.encoding, img.step) == (120, 160, "16UC1", 320)
        assert img.header.frame_id == "test_small_optical_frame"
        depth = img.data.view("<u2").reshape(120, 160)
        assert np.count_nonzero(depth) > 0.5 * depth.size
        seq, ts, n = struct.unpack_from("<qqB", att)
        assert len(att) == 33 and n == 16 and seq >= 1 and abs(ts - time.time_ns()) < 120e9
        seqs = [struct.unpack_from("<q", a)[0] for _, a in got["depth"]]
        assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
        gids = {a[17:] for leaf in got for _, a in got[leaf]}
        assert len(gids) == 8  # one GID per publisher
        info = store.deserialize_cdr(got["depth_info"][-1][0], "sensor_msgs/msg/CameraInfo")
        g = profile.geometry
        assert list(info.k) == [g.focal_px, 0, g.cx_camera, 0, g.focal_px, g.cy, 0, 0, 1]
        assert (info.width, info.height, info.header.frame_id) == (160, 120, "test_small_optical_frame")
        conf = store.deserialize_cdr(got["confidence"][-1][0], "sensor_msgs/msg/Image")
        assert conf.encoding == "mono8" and conf.step == 160
        # the error image: 32FC1, NaN exactly where there is no depth, the values of the result it came with
        by_stamp = {r.timestamp_ns: r for r in collect.results}
        for payload, _ in got["error"]:
            err = store.deserialize_cdr(payload, "sensor_msgs/msg/Image")
            assert (err.height, err.width, err.encoding, err.step, err.is_bigendian) == (120, 160, "32FC1", 640, 0)
            assert err.header.frame_id == "test_small_optical_frame"
            r = by_stamp[err.header.stamp.sec * 1_000_000_000 + err.header.stamp.nanosec]
            e = err.data.view("<f4").reshape(120, 160)
            assert r.error is not None and np.array_equal(e, r.error, equal_nan=True)
            assert np.array_equal(np.isnan(e), r.depth_mm == 0) and np.nanmax(e) <= 0.5
            assert np.count_nonzero(e[r.depth_mm > 0]) > 0  # real values, not a blank image
        error_info = store.deserialize_cdr(got["error_info"][-1][0], "sensor_msgs/msg/CameraInfo")
        assert list(error_info.k) == list(info.k) and error_info.header.frame_id == "test_small_optical_frame"
        cloud = store.deserialize_cdr(got["points"][-1][0], "sensor_msgs/msg/PointCloud2")
        xyz = cloud.data.view("<f4").reshape(-1, 3)
        assert cloud.point_step == 12 and cloud.width == xyz.shape[0] > 1000 and cloud.is_dense
        assert np.all(xyz[:, 2] > 0) and np.all(np.isfinite(xyz))
        tfm = store.deserialize_cdr(got["tf"][-1][0], "tf2_msgs/msg/TFMessage")
        tree = {(t.header.frame_id, t.child_frame_id): t.transform for t in tfm.transforms}
        assert set(tree) == {("test_small_link", "test_small_optical_frame"),
                             ("test_small_optical_frame", "test_small_projector_optical_frame")}
        assert tree[("test_small_optical_frame", "test_small_projector_optical_frame")].translation.x == g.baseline_m
        q = tree[("test_small_link", "test_small_optical_frame")].rotation
        assert (q.x, q.y, q.z, q.w) == (-0.5, 0.5, -0.5, 0.5)
        # tokens go away with the service
        left = [r for r in client.liveliness().get("@ros2_lv/3/**", timeout=2) if r.ok is not None]
        assert left == []
    finally:
        client.close()
        router.close()


def test_error_image_only_with_results_that_have_one():
    """A result without an error image (the "confidence" rule) publishes depth but nothing on the
    error topics; the next one, with an error image, publishes it (samples of one session arrive in
    order, so the first result's absence is observed, not timed)."""
    from edge.io.ros_sink import RosSink
    from edge.profiles import apply_update
    from edge.runtime.result import DepthResult

    router_ep = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(_conf("router", listen=[router_ep]))
    client = zenoh.open(_conf("client", connect=[router_ep]))
    session = zenoh.open(_conf("client", connect=[router_ep]))
    profile = apply_update(load_test_profile(), {"ros": {"enabled": True, "router": router_ep},
                                                 "points": {"publish": False}})
    got: dict[str, list] = {"depth": [], "error": [], "error_info": []}
    lock = threading.Lock()

    def on(leaf):
        def cb(sample):
            with lock:
                got[leaf].append(sample.payload.to_bytes())
        return cb

    sink = None
    subs = []
    try:
        sink = RosSink(profile, session=session, environ={})
        subs = [client.declare_subscriber(sink.keys[leaf], on(leaf)) for leaf in got]
        deadline = time.time() + 30  # until the subscriptions have reached the sink's session
        while time.time() < deadline and not all(sink._publishers[leaf].publisher.matching_status.matching
                                                 for leaf in got):
            time.sleep(0.05)
        depth = np.zeros((4, 5), np.uint16)
        depth[1:3, 1:4] = 800
        error = np.where(depth > 0, np.float32(0.01), np.float32(np.nan)).astype(np.float32)
        error[1, 1] = 0.2

        def result(stamp, err):
            return DepthResult(stack=stamp, sequence=stamp, timestamp_ns=stamp * 1_000_000_000 + 7, received_ns=0,
                               depth_mm=depth, confidence=(depth > 0).astype(np.uint8) * 200,
                               column=np.where(depth > 0, 10, -1).astype(np.int32), error=err)

        sink.on_result(result(1, None))
        sink.on_result(result(2, error))
        deadline = time.time() + 30
        while time.time() < deadline and not (len(got["depth"]) == 2 and len(got["error_info"]) == 1):
            time.sleep(0.05)
    finally:
        for sub in subs:
            sub.undeclare()
        if sink is not None:
            sink.close()
        session.close()
        client.close()
        router.close()
    store = _store()
    assert len(got["depth"]) == 2 and len(got["error"]) == 1 and len(got["error_info"]) == 1, \
        {k: len(v) for k, v in got.items()}
    img = store.deserialize_cdr(got["error"][0], "sensor_msgs/msg/Image")
    assert (img.header.stamp.sec, img.header.stamp.nanosec) == (2, 7)
    assert (img.height, img.width, img.encoding, img.step) == (4, 5, "32FC1", 20)
    assert np.array_equal(img.data.view("<f4").reshape(4, 5), error, equal_nan=True)
    info = store.deserialize_cdr(got["error_info"][0], "sensor_msgs/msg/CameraInfo")
    assert (info.header.stamp.sec, info.width, info.height) == (2, 5, 4)


def test_run_ros_flag_connects_to_the_router_and_defaults_avoid_7447():
    from argparse import Namespace

    from edge.commands.run import load_run_profile
    from edge.profiles import load_profile

    for name in ("sim-dlp", "oak-d-pro", "event-dots", "light-curtain"):
        assert not any(ep.endswith(":7447") for ep in load_profile(name).zenoh.listen), name
    p = load_run_profile(Namespace(profile="sim-dlp", listen=None, connect=None, ros=True))
    assert p.ros.enabled and "tcp/localhost:7447" in p.zenoh.connect
    assert not any(ep.endswith(":7447") for ep in p.zenoh.listen)
    p = load_run_profile(Namespace(profile="sim-dlp", listen=None, connect=None, ros=False))
    assert not p.ros.enabled and p.zenoh.connect == ()


def test_edge_run_ros_cli_publishes_through_the_router(tmp_path, capsys):
    """`edge run --ros` end to end (CLI: profile, sinks, shutdown order) against an in-process router."""
    from _service_helpers import TEST_PROFILE

    from edge.cli import main

    router_ep = f"tcp/127.0.0.1:{free_port()}"
    profile = tmp_path / "ros-small.toml"
    profile.write_text(TEST_PROFILE.read_text() + f'\n[ros]\nrouter = "{router_ep}"\n')
    router = zenoh.open(_conf("router", listen=[router_ep]))
    client = zenoh.open(_conf("client", connect=[router_ep]))
    got = []
    key = f"0/test_small/depth/image_rect_raw/sensor_msgs::msg::dds_::Image_/{IMAGE_HASH}"
    sub = client.declare_subscriber(key, lambda s: got.append(s.payload.to_bytes()))
    try:
        rc = main(["run", "--profile", str(profile), "--ros", "--stacks", "3", "--quiet",
                   "--listen", f"tcp/127.0.0.1:{free_port()}"])
        deadline = time.monotonic() + 10  # samples still on their way through the router
        while not got and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        sub.undeclare()
        client.close()
        router.close()
    out = capsys.readouterr()
    assert rc == 0, out
    assert f"ROS 2 via {router_ep}" in out.out
    assert len(got) >= 1
    img = _store().deserialize_cdr(got[-1], "sensor_msgs/msg/Image")
    assert (img.width, img.height, img.encoding) == (160, 120, "16UC1")

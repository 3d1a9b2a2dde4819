"""Point clouds: the back-projection function, the MCAP point cloud / calibration / frame tree
(read with the plain mcap reader and the foxglove protobuf classes), the live points key, and PLY
from the CLI (`edge subscribe --ply`, `edge replay --ply`)."""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest

from _service_helpers import NumpyPipeline, load_test_profile
from _ports import free_port


def test_depth_to_points_back_projects_a_plane_and_skips_invalid():
    from edge.runtime.depth import camera_matrix, depth_to_points
    from edge.sim import Geometry

    g = Geometry(focal_px=500.0, baseline_m=0.1, cx_camera=40.0, cx_projector=60.0, cy=30.0)
    k = camera_matrix(g)
    depth = np.full((60, 80), 1500, np.uint16)
    depth[10, 20] = 0
    pts = depth_to_points(depth, k)
    assert pts.dtype == np.float32 and pts.shape == (60 * 80 - 1, 3)
    assert np.allclose(pts[:, 2], 1.5)
    # pixel (u=0, v=0) and (u=79, v=59): x = (u - cx) z / f, y = (v - cy) z / f
    assert np.allclose(pts[0], [(0 - 40) * 1.5 / 500, (0 - 30) * 1.5 / 500, 1.5], atol=1e-6)
    assert np.allclose(pts[-1], [(79 - 40) * 1.5 / 500, (59 - 30) * 1.5 / 500, 1.5], atol=1e-6)
    # re-projecting every point lands on its pixel
    uvw = pts.astype(np.float64) @ k.T
    uv = uvw[:, :2] / uvw[:, 2:]
    vv, uu = np.nonzero(depth)
    assert np.allclose(uv, np.stack([uu, vv], 1), atol=1e-3)
    sub = depth_to_points(depth, k, stride=2)
    assert sub.shape == (30 * 40 - 1, 3)  # (10, 20) is on the stride grid and invalid
    with pytest.raises(ValueError, match="uint16"):
        depth_to_points(depth.astype(np.float32), k)
    with pytest.raises(ValueError, match="stride"):
        depth_to_points(depth, k, stride=0)


def _record(tmp_path, stacks=3):
    from edge.io.recording import RecordingThread
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile()
    path = tmp_path / "rec.mcap"
    recorder = RecordingThread(path, profile)
    service = Service(profile, SimSensor(profile, poses=2), recorder=recorder)
    service.run(stacks=stacks)
    return profile, path


def test_recording_has_points_and_calibration_per_depth_on_one_frame_tree(tmp_path):
    from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
    from mcap.reader import make_reader

    from edge.cli import main
    from edge.io.ply import read_ply
    from edge.runtime.depth import camera_matrix, depth_to_points

    profile, path = _record(tmp_path)
    by_topic: dict[str, list] = {}
    stacks = []  # stack id of every recorded depth map, in order (output_info precedes its depth)
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        for schema, channel, message in reader.iter_messages():
            if channel.topic == "/test-small/output_info":
                stacks.append(json.loads(message.data)["stack"])
            cls = {"foxglove.RawImage": RawImage, "foxglove.PointCloud": PointCloud,
                   "foxglove.CameraCalibration": CameraCalibration,
                   "foxglove.FrameTransforms": FrameTransforms}.get(schema.name if schema else "")
            if cls is None:
                continue
            msg = cls()
            msg.ParseFromString(message.data)
            by_topic.setdefault(channel.topic, []).append((message.log_time, msg))
    depth, points = by_topic["/test-small/depth"], by_topic["/test-small/points"]
    calib, tf = by_topic["/test-small/calibration"], by_topic["/test-small/tf"]
    assert len(depth) == len(points) >= 3 and len(calib) == len(depth) + 1
    frame = "test_small_optical_frame"
    assert {m.frame_id for _, m in depth + points + calib} == {frame}
    # a calibration with the timestamp of every depth map
    assert {t for t, _ in depth} <= {t for t, _ in calib}
    transforms = {(t.parent_frame_id, t.child_frame_id): t for t in tf[0][1].transforms}
    assert set(transforms) == {("test_small_link", frame), (frame, "test_small_projector_optical_frame")}
    assert transforms[(frame, "test_small_projector_optical_frame")].translation.x == pytest.approx(
        profile.geometry.baseline_m)
    # the cloud is the depth map back-projected at the profile's stride
    _, d = depth[-1]
    dm = np.frombuffer(d.data, "<u2").reshape(d.height, d.width)
    _, pc = points[-1]
    xyz = np.frombuffer(pc.data, "<f4").reshape(-1, 3)
    assert [(f.name, f.offset, f.type) for f in pc.fields] == [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    expect = depth_to_points(dm, camera_matrix(profile.geometry), stride=profile.points.stride)
    assert np.array_equal(xyz, expect) and len(xyz) > 0.1 * dm.size / profile.points.stride ** 2
    # PLY of every re-decoded depth map from the CLI
    out = tmp_path / "ply"
    assert main(["replay", str(path), "--ply", str(out)]) == 0
    files = sorted(out.glob("test-small_*.ply"))
    assert len(files) >= 2  # every stack replay re-decodes (complete in the file) gets one
    for file in files:
        stack = int(file.stem.rsplit("_", 1)[1])
        _, d = depth[stacks.index(stack)]
        dm = np.frombuffer(d.data, "<u2").reshape(d.height, d.width)
        cloud, grey = read_ply(file)
        full = depth_to_points(dm, camera_matrix(profile.geometry))
        assert np.array_equal(cloud, full) and grey is not None and grey.shape == (len(full), 3)


def test_points_key_and_subscribe_ply(tmp_path, capsys):
    from edge.cli import main
    from edge.io.ply import read_ply
    from edge.profiles import apply_update
    from edge.io.publish import ZenohSink
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    profile = apply_update(load_test_profile(), {"zenoh": {"listen": [endpoint]}})
    service = Service(profile, SimSensor(profile, poses=2), pipeline_factory=NumpyPipeline)
    service.sinks.append(ZenohSink(profile, service))
    runner = threading.Thread(target=service.run, kwargs={"seconds": 60})
    runner.start()
    out = tmp_path / "cloud.ply"
    try:
        rc = main(["subscribe", "--device", "test-small", "--connect", endpoint, "--count", "3",
                   "--seconds", "60", "--ply", str(out)])
    finally:
        service.stop()
        runner.join(60)
    assert rc == 0, capsys.readouterr().out
    xyz, _ = read_ply(out)
    assert xyz.shape[1] == 3 and len(xyz) > 500 and np.all(xyz[:, 2] > 0)
    assert "test_small_optical_frame" in capsys.readouterr().out

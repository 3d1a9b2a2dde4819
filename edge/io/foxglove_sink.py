"""Foxglove live sink: the Foxglove WebSocket protocol server of ``foxglove-sdk`` (optional extra
``edge[foxglove]``).

`FoxgloveSink` starts a server on ``host:port`` (default 127.0.0.1:8765; ``edge run --foxglove
[PORT]``) in its own `foxglove.Context` and logs, per depth map, on the same topics and with the
same schemas as a recording (`edge.io.mcap_format`), so one layout (docs/foxglove/edge-layout.json)
serves both:

====================================  ============================  ==========================
topic                                 schema                        content
====================================  ============================  ==========================
``/<device>/depth``                   foxglove.RawImage             16UC1 millimetres
``/<device>/error``                   foxglove.RawImage             32FC1 P(wrong), NaN = none
                                                                    (the "error" rule only)
``/<device>/confidence``              foxglove.RawImage             mono8
``/<device>/calibration``             foxglove.CameraCalibration    with every depth map
``/<device>/points``                  foxglove.PointCloud           ``[points] publish``
``/<device>/tf``                      foxglove.FrameTransforms      with every depth map
``/<device>/status``                  JSON                          the service status
====================================  ============================  ==========================

Frame ids: `edge.io.ros.frame_ids` (``<name>_link`` -> ``<name>_optical_frame`` ->
``<name>_projector_optical_frame``).  Without foxglove-sdk installed, constructing the sink raises
a ValueError that names the extra; the rest of edge does not import it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from edge.io.ros import OPTICAL_ROTATION, frame_ids

from edge.runtime.result import DepthResult


def _require_foxglove():
    try:
        import foxglove
        from foxglove import channels, messages
    except ImportError:
        raise ValueError("--foxglove needs the foxglove-sdk package: pip install 'edge[foxglove]'") from None
    return foxglove, channels, messages


class FoxgloveSink:
    """Service sink serving depth, confidence, calibration, point cloud and frame tree to Foxglove."""

    def __init__(self, profile, *, port: int = 8765, host: str = "127.0.0.1") -> None:
        foxglove, channels, messages = _require_foxglove()
        if not 0 <= int(port) <= 65535:
            raise ValueError(f"expected a Foxglove port 0..65535, got {port}")
        self.profile = profile
        self._m = messages
        dev = profile.zenoh.device
        self.frames = frame_ids(dev)
        self.context = foxglove.Context()
        ctx = self.context
        self.topics = {leaf: f"/{dev}/{leaf}" for leaf in ("depth", "error", "confidence", "calibration", "points", "tf",
                                                           "status")}
        self._depth = channels.RawImageChannel(self.topics["depth"], context=ctx)
        self._error = channels.RawImageChannel(self.topics["error"], context=ctx)
        self._confidence = channels.RawImageChannel(self.topics["confidence"], context=ctx)
        self._calibration = channels.CameraCalibrationChannel(self.topics["calibration"], context=ctx)
        self._points = channels.PointCloudChannel(self.topics["points"], context=ctx)
        self._tf = channels.FrameTransformsChannel(self.topics["tf"], context=ctx)
        self._status = foxglove.Channel(self.topics["status"], message_encoding="json", context=ctx)
        try:
            self.server = foxglove.start_server(name=f"edge {dev}", host=host, port=int(port), context=ctx)
        except Exception as exc:
            raise ValueError(f"could not start the Foxglove server on {host}:{port}: {exc}") from None
        self.port = self.server.port

    def _stamp(self, timestamp_ns: int):
        return self._m.Timestamp(sec=int(timestamp_ns) // 1_000_000_000, nsec=int(timestamp_ns) % 1_000_000_000)

    def _image(self, image: np.ndarray, encoding: str, timestamp_ns: int):
        return self._m.RawImage(timestamp=self._stamp(timestamp_ns), frame_id=self.frames["optical"],
                                width=image.shape[1], height=image.shape[0], encoding=encoding,
                                step=image.shape[1] * image.dtype.itemsize,
                                data=np.ascontiguousarray(image, dtype=image.dtype.newbyteorder("<")).tobytes())

    def _transforms(self, timestamp_ns: int, baseline_m: float):
        m = self._m
        ts = self._stamp(timestamp_ns)
        x, y, z, w = OPTICAL_ROTATION
        return m.FrameTransforms(transforms=[
            m.FrameTransform(timestamp=ts, parent_frame_id=self.frames["base"], child_frame_id=self.frames["optical"],
                             translation=m.Vector3(x=0.0, y=0.0, z=0.0), rotation=m.Quaternion(x=x, y=y, z=z, w=w)),
            m.FrameTransform(timestamp=ts, parent_frame_id=self.frames["optical"],
                             child_frame_id=self.frames["projector"],
                             translation=m.Vector3(x=float(baseline_m), y=0.0, z=0.0),
                             rotation=m.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))])

    def on_result(self, result: DepthResult) -> None:
        """Log the depth map's messages on every channel a client subscribed to (nothing is encoded
        for a channel without a subscriber)."""
        from edge.runtime.points import result_intrinsics, result_points

        m, t = self._m, result.timestamp_ns
        geometry = result.geometry if result.geometry is not None else self.profile.geometry
        h, w = result.depth_mm.shape
        if self._tf.has_sinks():
            self._tf.log(self._transforms(t, geometry.baseline_m), log_time=t)
        if self._calibration.has_sinks():
            k = [float(v) for v in result_intrinsics(result, self.profile.geometry).ravel()]
            self._calibration.log(m.CameraCalibration(
                timestamp=self._stamp(t), frame_id=self.frames["optical"], width=w, height=h,
                distortion_model="plumb_bob", D=[0.0] * 5, K=k, R=[1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
                P=[k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, 0.0, 0.0, 1.0, 0.0]), log_time=t)
        if self._depth.has_sinks():
            self._depth.log(self._image(result.depth_mm, "16UC1", t), log_time=t)
        if result.error is not None and self._error.has_sinks():
            self._error.log(self._image(result.error, "32FC1", t), log_time=t)
        if self._confidence.has_sinks():
            self._confidence.log(self._image(result.confidence, "mono8", t), log_time=t)
        if self.profile.points.publish and self._points.has_sinks():
            pts = result_points(result, self.profile.geometry, self.profile.points.stride)
            f32 = m.PackedElementFieldNumericType.Float32
            self._points.log(m.PointCloud(
                timestamp=self._stamp(t), frame_id=self.frames["optical"], point_stride=12,
                pose=m.Pose(position=m.Vector3(x=0.0, y=0.0, z=0.0), orientation=m.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
                fields=[m.PackedElementField(name=c, offset=4 * i, type=f32) for i, c in enumerate("xyz")],
                data=np.ascontiguousarray(pts, dtype="<f4").tobytes()), log_time=t)

    def on_status(self, status: dict[str, Any]) -> None:
        import json

        if self._status.has_sinks():
            self._status.log(json.loads(json.dumps(status, default=str)))

    def close(self) -> None:
        server, self.server = getattr(self, "server", None), None
        if server is not None:
            server.stop()

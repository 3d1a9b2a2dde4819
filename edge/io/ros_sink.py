"""ROS 2 sink: depth, error probability, confidence, camera info and point cloud as rmw_zenoh
publishers (no bridge).

`RosSink` declares, on a zenoh session connected to the ``rmw_zenohd`` router (``[ros] router``,
default ``tcp/localhost:7447``), one ROS node ``/<node>`` (``[ros] node``, default the device name
with ``-`` -> ``_``; namespace ``/``, enclave ``/``) and eight publishers (seven without
``[points] publish``), each with its ``@ros2_lv`` liveliness token (wire format in `edge.io.ros`):

====================================  ==========================  ===============================
topic                                 type                        content
====================================  ==========================  ===============================
``/<node>/depth/image_rect_raw``      sensor_msgs/msg/Image       16UC1 millimetres, 0 = invalid
``/<node>/depth/camera_info``         sensor_msgs/msg/CameraInfo  with every depth image
``/<node>/error/image_rect_raw``      sensor_msgs/msg/Image       32FC1 estimated P(the pixel's
                                                                  column, so its depth, is wrong),
                                                                  NaN = no depth / no estimate;
                                                                  only with depth maps that have
                                                                  one (`DepthResult.error`: the
                                                                  "error" validity rule)
``/<node>/error/camera_info``         sensor_msgs/msg/CameraInfo  with every error image
``/<node>/confidence/image_rect_raw`` sensor_msgs/msg/Image       mono8, higher = more confident
``/<node>/confidence/camera_info``    sensor_msgs/msg/CameraInfo  with every confidence image
``/<node>/depth/points``              sensor_msgs/msg/PointCloud2 x y z float32 (``[points]``)
``/tf``                               tf2_msgs/msg/TFMessage      with every depth map: the frame
                                                                  tree ``<name>_link`` -> optical
                                                                  -> projector optical frame
====================================  ==========================  ===============================

The error publishers are declared whatever the rule (as the zenoh sink's ``sl/<device>/error``):
under the "confidence" rule the topic is listed but nothing is published on it.  Per depth map the
order is depth, error, confidence, as on zenoh.

Every message has ``header.stamp`` = the time of the stack's last camera frame and ``frame_id``
``<name>_optical_frame`` with ``<name>`` the device name with ``-`` -> ``_`` (REP 103 / 105;
`edge.io.ros.frame_ids`; the same frame id as in recordings and the Foxglove sink, whatever the
node is called).  QoS: reliable, volatile, keep
last 10.  The domain is ``ROS_DOMAIN_ID`` (default 0).
"""

from __future__ import annotations

import os
import time
from typing import Any, Mapping

from edge.io import ros

from edge.runtime.result import DepthResult

IMAGE, INFO, CLOUD = "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo", "sensor_msgs/msg/PointCloud2"
TF = "tf2_msgs/msg/TFMessage"
#: leaf -> (topic below /<node>, ROS type)
TOPICS = {
    "depth": ("depth/image_rect_raw", IMAGE),
    "depth_info": ("depth/camera_info", INFO),
    "error": ("error/image_rect_raw", IMAGE),
    "error_info": ("error/camera_info", INFO),
    "confidence": ("confidence/image_rect_raw", IMAGE),
    "confidence_info": ("confidence/camera_info", INFO),
    "points": ("depth/points", CLOUD),
    "tf": ("/tf", TF),  # absolute: the tf tree is global
}


class _Publisher:
    def __init__(self, session: Any, key: str, token: str) -> None:
        self.key, self.token_key = key, token
        self.gid = ros.entity_gid(token)
        self.sequence = 0
        self.publisher = session.declare_publisher(key)
        self.token = session.liveliness().declare_token(token)

    def put(self, ros_type: str, msg: Mapping[str, Any]) -> None:
        self.sequence += 1
        self.publisher.put(ros.serialize_cdr(ros_type, msg),
                           attachment=ros.attachment(self.sequence, time.time_ns(), self.gid))

    def undeclare(self) -> None:
        for entity in (self.token, self.publisher):
            try:
                entity.undeclare()
            except Exception:
                pass


class RosSink:
    """Service sink publishing every `DepthResult` to ROS 2 over rmw_zenoh (see module docstring).

    session: a zenoh session to declare on (e.g. the zenoh sink's, so one session serves both key
    spaces; it must connect to the router); default: one opened from ``profile.zenoh`` plus
    ``profile.ros.router`` (closed by `close`).  environ: where ``ROS_DOMAIN_ID`` is read.
    """

    def __init__(self, profile, *, session: Any = None, environ: Mapping[str, str] | None = None) -> None:
        import dataclasses

        from edge.io.zenoh import open_session

        self.profile = profile
        self.domain_id = ros.domain_id_from_env(os.environ if environ is None else environ)
        self.node = profile.ros.node or ros.ros_name(profile.zenoh.device)
        self.frame_id = ros.frame_ids(profile.zenoh.device)["optical"]  # as in recordings and Foxglove
        self._own_session = session is None
        if session is None:
            z = profile.zenoh
            connect = tuple(z.connect) + ((profile.ros.router,) if profile.ros.router not in z.connect else ())
            session = open_session(dataclasses.replace(z, connect=connect))
        self.session = session
        self.zid = str(session.info.zid())
        self.topics = {leaf: t if t.startswith("/") else f"/{self.node}/{t}" for leaf, (t, _) in TOPICS.items()}
        self._publishers: dict[str, _Publisher] = {}
        try:
            self.node_token_key = ros.node_token(self.domain_id, self.zid, 0, self.node)
            self._node_token = session.liveliness().declare_token(self.node_token_key)
            for entity_id, (leaf, (_, ros_type)) in enumerate(TOPICS.items(), start=1):
                if leaf == "points" and not profile.points.publish:
                    continue
                topic = self.topics[leaf]
                self._publishers[leaf] = _Publisher(
                    session, ros.topic_keyexpr(self.domain_id, topic, ros_type),
                    ros.publisher_token(self.domain_id, self.zid, 0, entity_id, self.node, topic, ros_type))
        except BaseException:
            self.close()
            raise

    @property
    def keys(self) -> dict[str, str]:
        """leaf -> topic key expression."""
        return {leaf: p.key for leaf, p in self._publishers.items()}

    @property
    def tokens(self) -> list[str]:
        """Every liveliness key this sink declared (node first)."""
        return [self.node_token_key] + [p.token_key for p in self._publishers.values()]

    def on_result(self, result: DepthResult) -> None:
        from edge.runtime.points import result_intrinsics, result_points

        t, fid = result.timestamp_ns, self.frame_id
        h, w = result.depth_mm.shape
        k = result_intrinsics(result, self.profile.geometry)
        info = ros.camera_info_message(k, w, h, timestamp_ns=t, frame_id=fid)
        pubs = self._publishers
        pubs["depth"].put(IMAGE, ros.image_message(result.depth_mm, timestamp_ns=t, frame_id=fid))
        pubs["depth_info"].put(INFO, info)
        if result.error is not None:  # 32FC1, NaN where there is no depth or no estimate
            pubs["error"].put(IMAGE, ros.image_message(result.error, timestamp_ns=t, frame_id=fid))
            pubs["error_info"].put(INFO, info)
        pubs["confidence"].put(IMAGE, ros.image_message(result.confidence, timestamp_ns=t, frame_id=fid))
        pubs["confidence_info"].put(INFO, info)
        geometry = result.geometry if result.geometry is not None else self.profile.geometry
        pubs["tf"].put(TF, ros.tf_message(self.profile.zenoh.device, geometry.baseline_m, timestamp_ns=t))
        if "points" in pubs:
            pts = result_points(result, self.profile.geometry, self.profile.points.stride)
            pubs["points"].put(CLOUD, ros.point_cloud2_message(pts, timestamp_ns=t, frame_id=fid))

    def on_status(self, status: dict[str, Any]) -> None:
        pass

    def close(self) -> None:
        """Undeclare the tokens and publishers; close the session if this sink opened it.  Idempotent."""
        for p in self._publishers.values():
            p.undeclare()
        self._publishers = {}
        token = getattr(self, "_node_token", None)
        if token is not None:
            try:
                token.undeclare()
            except Exception:
                pass
            self._node_token = None
        if self._own_session and self.session is not None:
            self.session.close()
            self.session = None

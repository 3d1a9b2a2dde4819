"""What an edge MCAP recording contains: topics, schemas, and numpy <-> message conversion.

Topics (``<device>`` is ``profile.zenoh.device``; log_time = the frame's timestamp in ns):

==========================  ==========================  =======================================
topic                       schema (encoding)           content
==========================  ==========================  =======================================
``/<device>/raw``           foxglove.RawImage (pb)      every camera frame (patterns, white /
                                                        black calibration frames, EDC frames):
                                                        ``mono8`` (uint8) or ``mono16`` (uint16
                                                        LE); MCAP ``sequence`` = frame sequence
``/<device>/raw_info``      edge.FrameInfo (json)       one per raw frame, written just before
                                                        it: sequence, timestamp_ns, stack,
                                                        projector_frame, exposure_us, role, +
                                                        backend-specific keys
``/<device>/depth``         foxglove.RawImage (pb)      ``16UC1`` millimetres, 0 = invalid
``/<device>/confidence``    foxglove.RawImage (pb)      ``mono8``, higher = more confident
``/<device>/error``         foxglove.RawImage (pb)      ``32FC1``: the decoder's estimated
                                                        P(wrong column) of each depth pixel, NaN
                                                        where no depth / no estimate; only for
                                                        depth maps decoded under the "error"
                                                        rule (`edge.runtime.depth.error_image`),
                                                        written between depth and confidence
``/<device>/output_info``   edge.OutputInfo (json)      one per depth map, just before it:
                                                        stack, sequence, timestamp_ns + extras
``/<device>/stack``         edge.StackInfo (json)       one per decoded stack, before its depth:
                                                        stack, sequence, frames, extra_frames,
                                                        edc_rounds, received_ns, decode_ms,
                                                        edc_round_ms, edc_capture_ms, stats;
                                                        profile on the first stack a live
                                                        change decoded (replay switches there)
                                                        (`edge.io.recording.stack_info`); for a
                                                        complete stack the service did not
                                                        decode: stack, dropped ("stale",
                                                        "decode error")
``/<device>/calibration``   foxglove.CameraCalibration  camera intrinsics from the profile
                            (pb)                        geometry (plumb_bob, zero distortion):
                                                        one at the start and one per depth map
                                                        (same timestamp as the depth)
``/<device>/points``        foxglove.PointCloud (pb)    per depth map (``[points] record``):
                                                        x y z float32 metres, optical frame
``/<device>/tf``            foxglove.FrameTransforms    at the start: ``<name>_link`` ->
                            (pb)                        ``<name>_optical_frame`` -> ``<name>_
                                                        projector_optical_frame`` (+baseline x)
``/<device>/events``        edge.EventSlice (pb)        event sensors only (registered on the
                                                        first slice): the events of one slot,
                                                        column-wise x, y, t, p plus sequence,
                                                        stack, projector_frame, time window;
                                                        MCAP ``sequence`` = slice sequence
                                                        (`edge.io.event_record`)
==========================  ==========================  =======================================

Frame ids (`edge.io.ros.frame_ids`, REP 103 / 105, ``<name>`` = device with ``-`` -> ``_``):
images, calibration and points are in ``<name>_optical_frame``, so Foxglove projects the depth
image and draws the cloud in one frame tree.

``/<device>/config_change`` (edge.ConfigChange, json) holds every config update the running service
accepted: time_ns, keys, update, profile (`edge.io.recording`), at the time it was accepted; the
stack from which it decoded is the one whose ``/<device>/stack`` message carries the profile.

Further topics are added through `edge.io.mcap_writer.Recorder.register_channel` (same
``/<device>/<leaf>`` naming); `topics` lists the standard ones that every recording has.

Metadata records: ``edge.profile`` {"name", "json" (profile_to_dict as JSON), "sha256"},
``edge.sensor`` (free str -> str map from the backend) and ``edge.recording`` {"format"}: the
recording format, `RECORDING_FORMAT` (absent: 1; 2: a valid pixel's confidence is at least 1,
stacks carry live profile changes and dropped-stack markers). Attachment ``profile.json`` holds the same
profile JSON (media type application/json). MCAP header profile: ``edge``.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

from .ros import OPTICAL_ROTATION, frame_ids

__all__ = [
    "MCAP_PROFILE",
    "PROFILE_METADATA",
    "SENSOR_METADATA",
    "RECORDING_METADATA",
    "RECORDING_FORMAT",
    "PROFILE_ATTACHMENT",
    "topics",
    "image_to_raw",
    "raw_to_image",
    "camera_calibration",
    "point_cloud",
    "cloud_to_points",
    "frame_transforms",
    "profile_json",
    "JSON_SCHEMAS",
]

MCAP_PROFILE = "edge"
PROFILE_METADATA = "edge.profile"
SENSOR_METADATA = "edge.sensor"
RECORDING_METADATA = "edge.recording"
#: Format of the recordings this code writes (see the module docstring; 1 = older, no record).
RECORDING_FORMAT = 2
PROFILE_ATTACHMENT = "profile.json"

# Encodings written for each dtype, and the dtype read back for each encoding.
_RAW_ENCODING = {np.dtype(np.uint8): "mono8", np.dtype(np.uint16): "mono16"}
_DECODE = {"mono8": np.dtype(np.uint8), "8UC1": np.dtype(np.uint8),
           "mono16": np.dtype("<u2"), "16UC1": np.dtype("<u2"), "32FC1": np.dtype("<f4")}

JSON_SCHEMAS: dict[str, dict[str, Any]] = {
    "edge.FrameInfo": {
        "type": "object",
        "properties": {
            "sequence": {"type": "integer"}, "timestamp_ns": {"type": "integer"},
            "stack": {"type": "integer"}, "projector_frame": {"type": "integer"},
            "exposure_us": {"type": "number"}, "role": {"type": "string"},
        },
    },
    "edge.OutputInfo": {
        "type": "object",
        "properties": {
            "stack": {"type": "integer"}, "sequence": {"type": "integer"},
            "timestamp_ns": {"type": "integer"},
        },
    },
    "edge.StackInfo": {
        "type": "object",
        "properties": {
            "stack": {"type": "integer"}, "sequence": {"type": "integer"}, "frames": {"type": "integer"},
            "extra_frames": {"type": "integer"}, "edc_rounds": {"type": "integer"},
            "received_ns": {"type": "integer"}, "decode_ms": {"type": "number"},
            "edc_round_ms": {"type": "array", "items": {"type": "number"}},
            "edc_capture_ms": {"type": "array", "items": {"type": "number"}}, "stats": {"type": "object"},
            "profile": {"type": "object"}, "dropped": {"type": "string"},
        },
    },
}


def topics(device: str) -> dict[str, str]:
    """Topic names for one device: keys raw, raw_info, depth, error, confidence, output_info, stack,
    calibration, points, tf."""
    return {leaf: f"/{device}/{leaf}" for leaf in
            ("raw", "raw_info", "depth", "error", "confidence", "output_info", "stack", "calibration", "points", "tf")}


def _timestamp(msg: Any, timestamp_ns: int) -> None:
    msg.timestamp.seconds = int(timestamp_ns) // 1_000_000_000
    msg.timestamp.nanos = int(timestamp_ns) % 1_000_000_000


def image_to_raw(image: np.ndarray, *, timestamp_ns: int, frame_id: str = "camera",
                 encoding: str | None = None) -> RawImage:
    """A foxglove.RawImage from an (H, W) uint8 or uint16 array, or a float32 one with ``encoding``
    ``32FC1`` (stored little-endian).

    ``encoding`` defaults to ``mono8`` / ``mono16``; pass ``16UC1`` for depth, ``32FC1`` for the
    error probability.
    """
    image = np.asarray(image)
    if image.ndim != 2 or not (image.dtype in _RAW_ENCODING or (image.dtype == np.float32 and encoding == "32FC1")):
        raise ValueError(f"expected an (H, W) uint8 or uint16 image (float32 with encoding 32FC1), got shape "
                         f"{image.shape} dtype {image.dtype}")
    if encoding is None:
        encoding = _RAW_ENCODING[image.dtype]
    if _DECODE.get(encoding, None) is None or _DECODE[encoding].itemsize != image.dtype.itemsize:
        raise ValueError(f"expected an encoding matching dtype {image.dtype}, got {encoding!r}")
    data = np.ascontiguousarray(image, dtype=image.dtype.newbyteorder("<")).tobytes()
    msg = RawImage(frame_id=frame_id, width=image.shape[1], height=image.shape[0], encoding=encoding,
                   step=image.shape[1] * image.dtype.itemsize, data=data)
    _timestamp(msg, timestamp_ns)
    return msg


def raw_to_image(msg: RawImage) -> np.ndarray:
    """The (H, W) array of a foxglove.RawImage (mono8 / 8UC1 -> uint8, mono16 / 16UC1 -> uint16,
    32FC1 -> float32)."""
    dtype = _DECODE.get(msg.encoding)
    if dtype is None:
        raise ValueError(f"expected a RawImage encoding in {sorted(_DECODE)}, got {msg.encoding!r}")
    row = msg.width * dtype.itemsize
    if msg.step < row or len(msg.data) < msg.step * msg.height:
        raise ValueError(f"RawImage of {msg.width}x{msg.height} {msg.encoding} with step {msg.step} "
                         f"needs {msg.step * msg.height} bytes, got {len(msg.data)}")
    flat = np.frombuffer(msg.data, dtype=np.uint8, count=msg.step * msg.height).reshape(msg.height, msg.step)
    out = flat[:, :row].copy().view(dtype).reshape(msg.height, msg.width)
    return out.astype(dtype.newbyteorder("="), copy=False)


def camera_calibration(geometry: Any, width: int, height: int, *, timestamp_ns: int = 0,
                       frame_id: str = "camera") -> CameraCalibration:
    """foxglove.CameraCalibration of the rectified camera in a profile's geometry (no distortion)."""
    f, cx, cy = float(geometry.focal_px), float(geometry.cx_camera), float(geometry.cy)
    msg = CameraCalibration(frame_id=frame_id, width=int(width), height=int(height),
                            distortion_model="plumb_bob", D=[0.0] * 5,
                            K=[f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0],
                            R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                            P=[f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0])
    _timestamp(msg, timestamp_ns)
    return msg


def point_cloud(xyz: np.ndarray, *, timestamp_ns: int, frame_id: str) -> PointCloud:
    """foxglove.PointCloud of (N, 3) points (metres): fields x y z FLOAT32, point_stride 12, LE."""
    xyz = np.ascontiguousarray(np.asarray(xyz), dtype="<f4")
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise ValueError(f"expected (N, 3) points, got {xyz.shape}")
    msg = PointCloud(frame_id=frame_id, point_stride=12, data=xyz.tobytes(),
                     fields=[PackedElementField(name=c, offset=4 * i, type=PackedElementField.FLOAT32)
                             for i, c in enumerate("xyz")])
    msg.pose.orientation.w = 1.0
    _timestamp(msg, timestamp_ns)
    return msg


def cloud_to_points(msg: PointCloud) -> np.ndarray:
    """(N, 3) float32 x y z of a foxglove.PointCloud written by `point_cloud`."""
    names = [(f.name, f.offset, f.type) for f in msg.fields]
    if names[:3] != [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)] or msg.point_stride < 12:
        raise ValueError(f"expected a PointCloud with float32 x y z at offsets 0 4 8, got {names}")
    n = len(msg.data) // msg.point_stride
    rows = np.frombuffer(msg.data, np.uint8, count=n * msg.point_stride).reshape(n, msg.point_stride)
    return rows[:, :12].copy().view("<f4").reshape(n, 3).astype(np.float32)


def frame_transforms(device: str, baseline_m: float, *, timestamp_ns: int) -> FrameTransforms:
    """foxglove.FrameTransforms of a device's frame tree (`edge.io.ros.frame_ids`): body -> camera
    optical frame (REP 103 rotation), optical -> projector optical frame (+baseline_m along x)."""
    ids = frame_ids(device)
    msg = FrameTransforms()
    t = msg.transforms.add(parent_frame_id=ids["base"], child_frame_id=ids["optical"])
    t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = OPTICAL_ROTATION
    _timestamp(t, timestamp_ns)
    p = msg.transforms.add(parent_frame_id=ids["optical"], child_frame_id=ids["projector"])
    p.translation.x = float(baseline_m)
    p.rotation.w = 1.0
    _timestamp(p, timestamp_ns)
    return msg


def profile_json(profile_dict: dict[str, Any]) -> tuple[str, str]:
    """(canonical JSON text, sha256 hex) of a profile dict."""
    text = json.dumps(profile_dict, sort_keys=True, separators=(",", ":"))
    return text, hashlib.sha256(text.encode()).hexdigest()

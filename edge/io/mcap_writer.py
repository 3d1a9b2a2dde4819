"""`Recorder`: write an edge recording (layout in `edge.io.mcap_format`) to an MCAP file.

Usage::

    with Recorder("out.mcap", profile, sensor_metadata={"backend": "sim"}) as rec:
        rec.write_frame(frame)                       # any object with image, sequence,
                                                     # timestamp_ns, stack, projector_frame,
                                                     # exposure_us (edge.sensors Frame)
        rec.write_raw(image, sequence=7, timestamp_ns=t, stack=0, projector_frame=3, role="pattern")
        rec.write_stack({"stack": 0, "frames": 24, "edc_rounds": 1}, timestamp_ns=t)
        rec.write_depth(depth_mm_u16, confidence_u8, timestamp_ns=t, stack=0, sequence=0)
        cid = rec.register_channel("events", "edge.EventSlice", "protobuf", descriptor_set_bytes)
        rec.write_message(cid, message_bytes, log_time_ns=t, sequence=7)   # extra topics
    # finish() ran: summary, indexes and CRCs are written even if the block raised.

Chunked (``profile.recording.chunk_size`` bytes), compressed (``profile.recording.compression``),
chunk / data-section / summary CRCs on. Every write takes a lock, so a capture thread and a decode
thread may share one Recorder. The file object is flushed after every write, so a killed process
leaves every completed chunk on disk for `edge.io.mcap.recover`.

Extra topics (``/<device>/<leaf>`` beyond the standard table of `edge.io.mcap_format`, e.g. the
event slices of `edge.io.event_record`) go through the public `Recorder.register_channel` /
`Recorder.write_message` pair; subclasses need no private members.
"""

from __future__ import annotations

import errno
import json
import os
import threading
import time
from typing import Any, Mapping

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from edge import __version__
from edge.profiles import Profile, profile_to_dict

from .ros import frame_ids
from .mcap_format import (
    JSON_SCHEMAS,
    MCAP_PROFILE,
    PROFILE_ATTACHMENT,
    PROFILE_METADATA,
    RECORDING_FORMAT,
    RECORDING_METADATA,
    SENSOR_METADATA,
    camera_calibration,
    frame_transforms,
    image_to_raw,
    point_cloud,
    profile_json,
    topics,
)

__all__ = ["Recorder", "RecordingStopped", "COMPRESSION", "MESSAGE_ENCODINGS"]

COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
#: message encoding -> schema encoding of the channels a Recorder writes
MESSAGE_ENCODINGS = {"protobuf": "protobuf", "json": "jsonschema"}


class RecordingStopped(OSError):
    """A write to a `Recorder` whose file already failed (disk full, I/O error); the message says why."""


class _TrackedFile:
    """The recording's file object: remembers the offset where the last successful ``flush`` ended
    (every Recorder write ends with one, so it is the end of the last complete record) and the
    first OSError (after which nothing more is written)."""

    def __init__(self, f: Any) -> None:
        self._f = f
        self.good = 0
        self.error: OSError | None = None

    def _fail(self, exc: OSError) -> None:
        if self.error is None:
            self.error = exc

    def write(self, data: Any) -> int:
        if self.error is not None:
            raise RecordingStopped(f"recording stopped after a write error: {self.error}")
        try:
            return self._f.write(data)
        except OSError as exc:
            self._fail(exc)
            raise

    def flush(self) -> None:
        if self.error is not None:
            raise RecordingStopped(f"recording stopped after a write error: {self.error}")
        try:
            self._f.flush()
        except OSError as exc:
            self._fail(exc)
            raise
        self.good = self._f.tell()

    def tell(self) -> int:
        return self._f.tell()

    def fileno(self) -> int:
        return self._f.fileno()

    def close(self) -> None:
        try:
            self._f.close()
        except OSError as exc:  # a failed file: the pending buffer cannot be written either
            self._fail(exc)
            try:
                self._f.close()
            except OSError:
                pass


class Recorder:
    """Writes one recording; see the module docstring. Not reusable after `finish`.

    Parameters: ``path`` (created / truncated), ``profile`` (recorded as metadata + attachment;
    gives the device name, chunk size and compression), ``sensor_metadata`` (str -> str, e.g.
    serial, firmware, backend), ``chunk_size`` / ``compression`` override the profile.

    Write failures (ENOSPC, EFBIG, EIO): the failing write raises OSError and every later write
    raises `RecordingStopped`; `finish` then cuts the file back to the end of the last complete
    write and finalises it in place (`edge.io.mcap_finalize`), so what reached the disk stays a
    valid recording (``finalize_report`` says what it holds; ``error`` the first failure).
    """

    def __init__(self, path: str | os.PathLike[str], profile: Profile, *,
                 sensor_metadata: Mapping[str, Any] | None = None,
                 chunk_size: int | None = None, compression: str | None = None):
        compression = compression or profile.recording.compression
        if compression not in COMPRESSION:
            raise ValueError(f"expected compression in {sorted(COMPRESSION)}, got {compression!r}")
        self.path = os.fspath(path)
        self.profile = profile
        self.topics = topics(profile.zenoh.device)
        self.frame_id = frame_ids(profile.zenoh.device)["optical"]
        self.messages_written = 0
        self.bytes_in = 0
        self._lock = threading.Lock()
        self._finished = False
        self.finalize_report = None
        self._file = _TrackedFile(open(self.path, "wb"))
        try:
            self._writer = Writer(self._file, chunk_size=chunk_size or profile.recording.chunk_size,
                                  compression=COMPRESSION[compression], enable_crcs=True,
                                  enable_data_crcs=True)
            self._writer.start(profile=MCAP_PROFILE, library=f"edge {__version__}")
            self._channels: dict[str, int] = {}          # leaf -> channel id
            self._channel_schema: dict[int, tuple[str, str, bytes]] = {}  # extra channels: id -> schema
            self._schemas: dict[tuple[str, str, bytes], int] = {}
            self._sequence: dict[int, int] = {}          # channel id -> next automatic sequence
            self._register()
            text, digest = profile_json(profile_to_dict(profile))
            now = time.time_ns()
            self._writer.add_metadata(PROFILE_METADATA, {"name": profile.name, "json": text, "sha256": digest})
            self._writer.add_metadata(RECORDING_METADATA, {"format": str(RECORDING_FORMAT)})
            self._writer.add_attachment(create_time=now, log_time=now, name=PROFILE_ATTACHMENT,
                                        media_type="application/json", data=text.encode())
            if sensor_metadata:
                self._writer.add_metadata(SENSOR_METADATA, {str(k): str(v) for k, v in sensor_metadata.items()})
            self._add("calibration", self._calibration(now), now, 0)
            self._tf_baseline = float(profile.geometry.baseline_m)  # of the last frame tree written
            tf = frame_transforms(profile.zenoh.device, self._tf_baseline, timestamp_ns=now)
            self._add("tf", tf.SerializeToString(), now, 0)
            self._file.flush()
        except BaseException:
            self._file.close()
            raise

    # -- setup -------------------------------------------------------------------------------

    def _register(self) -> None:
        proto = {}
        for cls in (RawImage, CameraCalibration, PointCloud, FrameTransforms):
            proto[cls.DESCRIPTOR.full_name] = self._writer.register_schema(
                name=cls.DESCRIPTOR.full_name, encoding="protobuf",
                data=build_file_descriptor_set(cls).SerializeToString())
        js = {name: self._writer.register_schema(name=name, encoding="jsonschema",
                                                 data=json.dumps(schema).encode())
              for name, schema in JSON_SCHEMAS.items()}
        layout = {
            "raw": ("protobuf", proto["foxglove.RawImage"]),
            "raw_info": ("json", js["edge.FrameInfo"]),
            "depth": ("protobuf", proto["foxglove.RawImage"]),
            "error": ("protobuf", proto["foxglove.RawImage"]),
            "confidence": ("protobuf", proto["foxglove.RawImage"]),
            "output_info": ("json", js["edge.OutputInfo"]),
            "stack": ("json", js["edge.StackInfo"]),
            "calibration": ("protobuf", proto["foxglove.CameraCalibration"]),
            "points": ("protobuf", proto["foxglove.PointCloud"]),
            "tf": ("protobuf", proto["foxglove.FrameTransforms"]),
        }
        for leaf, (encoding, schema_id) in layout.items():
            self._channels[leaf] = self._writer.register_channel(
                topic=self.topics[leaf], message_encoding=encoding, schema_id=schema_id)

    def _calibration(self, timestamp_ns: int, geometry: Any = None) -> bytes:
        p = self.profile
        return camera_calibration(p.geometry if geometry is None else geometry, p.camera.width, p.camera.height,
                                  timestamp_ns=timestamp_ns, frame_id=self.frame_id).SerializeToString()

    def _add(self, leaf: str, data: bytes, log_time: int, sequence: int | None = None) -> None:
        self._add_to(self._channels[leaf], data, log_time, sequence)

    def _add_to(self, channel_id: int, data: bytes, log_time: int, sequence: int | None = None) -> None:
        if sequence is None:
            sequence = self._sequence.get(channel_id, 0)
            self._sequence[channel_id] = sequence + 1
        self._writer.add_message(channel_id=channel_id, log_time=int(log_time), data=data,
                                 publish_time=int(log_time), sequence=int(sequence) & 0xFFFFFFFF)
        self.messages_written += 1
        self.bytes_in += len(data)

    def _check_open(self) -> None:
        if self._file.error is not None:
            raise RecordingStopped(f"recording {self.path} stopped after a write error: {self._file.error}")
        if self._finished:
            raise ValueError(f"recorder for {self.path} is finished; expected writes before finish()")

    # -- extra channels ----------------------------------------------------------------------

    def register_channel(self, leaf: str, schema_name: str, encoding: str, schema_data: bytes) -> int:
        """Add topic ``/<device>/<leaf>`` (message ``encoding`` ``protobuf`` or ``json``; the schema
        record is ``schema_name`` with encoding ``protobuf`` (``schema_data`` = a serialized
        FileDescriptorSet) or ``jsonschema`` (``schema_data`` = the JSON schema)) and return its
        channel id for `write_message`.  ``self.topics[leaf]`` names the topic afterwards.

        Idempotent: the same leaf with the same schema returns the same id (so it may be called
        lazily, on the first message); a standard leaf or another schema for a registered leaf is a
        ValueError.
        """
        if not leaf or "/" in leaf:
            raise ValueError(f"expected a topic leaf name without '/', got {leaf!r}")
        if encoding not in MESSAGE_ENCODINGS:
            raise ValueError(f"expected a message encoding in {sorted(MESSAGE_ENCODINGS)}, got {encoding!r}")
        key = (str(schema_name), MESSAGE_ENCODINGS[encoding], bytes(schema_data))
        with self._lock:
            self._check_open()
            if leaf in self._channels:
                cid = self._channels[leaf]
                if self._channel_schema.get(cid) != key:
                    raise ValueError(f"topic /{self.profile.zenoh.device}/{leaf} is already registered with "
                                     f"another schema; expected a new leaf or the schema {schema_name!r} it has")
                return cid
            schema_id = self._schemas.get(key)
            if schema_id is None:
                schema_id = self._schemas[key] = self._writer.register_schema(
                    name=key[0], encoding=key[1], data=key[2])
            topic = f"/{self.profile.zenoh.device}/{leaf}"
            cid = self._writer.register_channel(topic=topic, message_encoding=encoding, schema_id=schema_id)
            self.topics[leaf] = topic
            self._channels[leaf] = cid
            self._channel_schema[cid] = key
            self._file.flush()
            return cid

    def write_message(self, channel: int, data: bytes, *, log_time_ns: int, sequence: int | None = None) -> None:
        """One message on a channel from `register_channel`: ``data`` already serialized; MCAP
        log_time = publish_time = ``log_time_ns``; ``sequence`` (None = 0, 1, 2... per channel)."""
        with self._lock:
            self._check_open()
            if channel not in self._channel_schema:
                raise ValueError(f"expected a channel id from register_channel "
                                 f"({sorted(self._channel_schema)}), got {channel!r}")
            self._add_to(channel, bytes(data), log_time_ns, sequence)
            self._file.flush()

    # -- writes ------------------------------------------------------------------------------

    def write_raw(self, image: np.ndarray, *, sequence: int, timestamp_ns: int, stack: int,
                  projector_frame: int, exposure_us: float = 0.0, role: str = "pattern",
                  **extra: Any) -> None:
        """Record one camera frame: (H, W) uint8 (mono8) or uint16 (mono16) plus its metadata.

        ``extra`` keys (JSON-able) go into the ``raw_info`` message next to the standard ones.
        """
        msg = image_to_raw(image, timestamp_ns=timestamp_ns, frame_id=self.frame_id)
        info = {"sequence": int(sequence), "timestamp_ns": int(timestamp_ns), "stack": int(stack),
                "projector_frame": int(projector_frame), "exposure_us": float(exposure_us),
                "role": str(role), **extra}
        info_bytes = json.dumps(info).encode()
        raw_bytes = msg.SerializeToString()
        with self._lock:
            self._check_open()
            self._add("raw_info", info_bytes, timestamp_ns, sequence)
            self._add("raw", raw_bytes, timestamp_ns, sequence)
            self._file.flush()

    def write_frame(self, frame: Any, **extra: Any) -> None:
        """`write_raw` from a frame object with attributes image, sequence, timestamp_ns, stack,
        projector_frame and (optional) exposure_us, role, metadata (dict merged into extra)."""
        meta = dict(getattr(frame, "metadata", None) or {})
        meta.update(extra)
        role = meta.pop("role", getattr(frame, "role", "pattern"))
        self.write_raw(frame.image, sequence=frame.sequence, timestamp_ns=frame.timestamp_ns,
                       stack=frame.stack, projector_frame=frame.projector_frame,
                       exposure_us=getattr(frame, "exposure_us", 0.0), role=role, **meta)

    def write_depth(self, depth_mm: np.ndarray, confidence: np.ndarray, *, timestamp_ns: int,
                    stack: int, sequence: int, points: np.ndarray | None = None, geometry: Any = None,
                    error: np.ndarray | None = None, **extra: Any) -> None:
        """Record one output: depth (H, W) uint16 mm (0 = invalid) and confidence (H, W) uint8, the
        camera calibration with the same timestamp and, if given, its (N, 3) float32 points
        (metres, optical frame; `edge.runtime.depth.depth_to_points`) and its (H, W) float32
        error probability (``32FC1`` on ``/<device>/error``, NaN = no estimate;
        `edge.runtime.depth.error_image`).  ``geometry``: the geometry the depth was computed with
        (default: the profile's), for the calibration message, and for the frame tree: a ``tf``
        message with the same timestamp where its baseline differs from the last one written (a
        live geometry change)."""
        depth_mm, confidence = np.asarray(depth_mm), np.asarray(confidence)
        if depth_mm.dtype != np.uint16 or confidence.dtype != np.uint8 or depth_mm.shape != confidence.shape:
            raise ValueError("expected depth uint16 (H, W) and confidence uint8 of the same shape, got "
                             f"{depth_mm.dtype} {depth_mm.shape} and {confidence.dtype} {confidence.shape}")
        if error is not None:
            error = np.asarray(error)
            if error.dtype != np.float32 or error.shape != depth_mm.shape:
                raise ValueError(f"expected error float32 {depth_mm.shape}, got {error.dtype} {error.shape}")
        d = image_to_raw(depth_mm, timestamp_ns=timestamp_ns, encoding="16UC1",
                         frame_id=self.frame_id).SerializeToString()
        e = None if error is None else image_to_raw(error, timestamp_ns=timestamp_ns, encoding="32FC1",
                                                     frame_id=self.frame_id).SerializeToString()
        c = image_to_raw(confidence, timestamp_ns=timestamp_ns, encoding="mono8",
                         frame_id=self.frame_id).SerializeToString()
        calib = self._calibration(timestamp_ns, geometry)
        baseline = getattr(geometry if geometry is not None else self.profile.geometry, "baseline_m", None)
        tf = None
        if baseline is not None and float(baseline) != self._tf_baseline:
            tf = frame_transforms(self.profile.zenoh.device, float(baseline), timestamp_ns=timestamp_ns)
        cloud = None if points is None else point_cloud(points, timestamp_ns=timestamp_ns,
                                                        frame_id=self.frame_id).SerializeToString()
        info = json.dumps({"stack": int(stack), "sequence": int(sequence),
                           "timestamp_ns": int(timestamp_ns), **extra}).encode()
        with self._lock:
            self._check_open()
            self._add("output_info", info, timestamp_ns, sequence)
            self._add("depth", d, timestamp_ns, sequence)
            if e is not None:  # before confidence: the reader completes an output on its confidence
                self._add("error", e, timestamp_ns, sequence)
            self._add("confidence", c, timestamp_ns, sequence)
            self._add("calibration", calib, timestamp_ns)
            if tf is not None:
                self._add("tf", tf.SerializeToString(), timestamp_ns, 0)
                self._tf_baseline = float(baseline)
            if cloud is not None:
                self._add("points", cloud, timestamp_ns, sequence)
            self._file.flush()

    def write_stack(self, info: Mapping[str, Any], *, timestamp_ns: int) -> None:
        """Record per-stack metadata (JSON-able dict; by convention it has a ``stack`` key)."""
        data = json.dumps(dict(info)).encode()
        with self._lock:
            self._check_open()
            self._add("stack", data, timestamp_ns, int(info.get("stack", 0)))
            self._file.flush()

    def add_metadata(self, name: str, data: Mapping[str, Any]) -> None:
        """An extra MCAP metadata record (values converted to str)."""
        with self._lock:
            self._check_open()
            self._writer.add_metadata(name, {str(k): str(v) for k, v in data.items()})
            self._file.flush()

    # -- lifetime ----------------------------------------------------------------------------

    @property
    def finished(self) -> bool:
        return self._finished

    @property
    def error(self) -> str:
        """The first write failure ('' while the file is fine)."""
        e = self._file.error
        if e is None:
            return ""
        if e.errno:
            return f"{e.strerror or os.strerror(e.errno)} ({errno.errorcode.get(e.errno, e.errno)})"
        return str(e)

    @property
    def bytes_written(self) -> int:
        """Bytes known to be on disk (end of the last complete write)."""
        return self._file.good

    def finish(self) -> None:
        """Write the last chunk, summary, footer and close the file. Idempotent.

        After a write failure the file is cut back and finalised in place instead (see the class
        docstring); OSError only if even that fails (the cut file is left for ``edge replay --recover``).
        """
        from .mcap_finalize import finalize_in_place

        with self._lock:
            if self._finished:
                return
            self._finished = True
            try:
                if self._file.error is None:
                    self._writer.finish()
                    self._file.flush()
            except OSError:
                pass  # remembered by the file object; finalised below
            finally:
                self._file.close()
            if self._file.error is not None:
                self.finalize_report = finalize_in_place(self.path, self._file.good)

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.finish()

"""`RecordingReader`: read an edge MCAP recording back as numpy arrays with their metadata.

Usage::

    rec = RecordingReader("out.mcap", expected_profile=profile)   # ProfileMismatchError if other
    rec.profile                     # the recorded Profile (None if the file has none)
    rec.sensor_metadata             # dict[str, str]
    rec.complete                    # True if the file has a valid summary + footer
    for frame in rec.frames(): ...  # RecordedFrame: image (H, W) uint8/uint16, sequence,
                                    # timestamp_ns, stack, projector_frame, exposure_us, role, info
    for out in rec.outputs(): ...   # RecordedOutput: depth_mm uint16, confidence uint8, stack, ...
    for st in rec.stacks(): ...     # RecordedStack: stack, frames, images (n, H, W), info, output
    for m in rec.messages(): ...    # RecordedMessage: topic, log_time, sequence, schema, value

Reading is one sequential pass over the records (file order), with chunk CRCs and the data-section
CRC validated. A truncated or corrupt file yields everything readable, then raises
`TruncatedRecordingError` naming the byte offset reached and what was read (``strict=False``: stop
quietly and leave the message in ``reader.problem``). A non-MCAP file raises `NotMcapError` on open.
All errors are `RecordingError`, a ValueError, with one line of text.
"""

from __future__ import annotations

import io
import json
import os
import struct
from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Chunk, Footer, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk

from edge.profiles import Profile, ProfileError, changed_keys, profile_from_dict

from .mcap_format import PROFILE_METADATA, SENSOR_METADATA, raw_to_image

__all__ = [
    "RecordingError",
    "NotMcapError",
    "TruncatedRecordingError",
    "ProfileMismatchError",
    "RecordedMessage",
    "RecordedFrame",
    "RecordedOutput",
    "RecordedStack",
    "RecordingReader",
    "scan_records",
    "MCAP_MAGIC",
]

MCAP_MAGIC = b"\x89MCAP0\r\n"
# Profile sections that do not change what the decoder computes (ignored by the profile check).
_NOT_DECODING = ("description", "sensor.", "zenoh.", "recording.", "sim.")


class RecordingError(ValueError):
    """Any problem with a recording (one line)."""


class NotMcapError(RecordingError):
    """The file is not an MCAP file."""


class TruncatedRecordingError(RecordingError):
    """The file ends early or has a corrupt record; ``offset`` is where reading stopped."""

    def __init__(self, message: str, *, offset: int, total: int, messages: int):
        super().__init__(message)
        self.offset, self.total, self.messages = offset, total, messages


class ProfileMismatchError(RecordingError):
    """The recording was made with another profile than the one expected."""


@dataclass
class RecordedMessage:
    topic: str
    log_time: int
    sequence: int
    schema: str
    value: Any  # np.ndarray (RawImage), dict (JSON), CameraCalibration, or bytes (unknown)


@dataclass
class RecordedFrame:
    image: np.ndarray          # (H, W) uint8 or uint16
    sequence: int
    timestamp_ns: int
    stack: int
    projector_frame: int
    exposure_us: float
    role: str
    info: dict[str, Any] = field(default_factory=dict)  # the full raw_info message


@dataclass
class RecordedOutput:
    depth_mm: np.ndarray       # (H, W) uint16, 0 = invalid
    confidence: np.ndarray     # (H, W) uint8, higher = more confident
    timestamp_ns: int
    stack: int
    sequence: int
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class RecordedStack:
    stack: int
    frames: list[RecordedFrame]
    info: dict[str, Any] | None = None       # the /stack message, if recorded
    output: RecordedOutput | None = None     # the recorded depth / confidence, if any

    @property
    def images(self) -> np.ndarray:
        """(n, H, W) frames of the stack in recorded order."""
        return np.stack([f.image for f in self.frames])


def scan_records(f: io.BufferedReader, total: int) -> Iterator[tuple[Any, int]]:
    """Yield ``(record, end_offset)`` for every record in file order, chunks broken up.

    ``end_offset`` is the byte offset just past the top-level record the item came from (for a
    chunk's inner records: the end of the chunk). Chunk CRCs and the data-section CRC are checked;
    mcap exceptions (EndOfFile, CRCValidationError, ...) propagate to the caller.
    """
    reader = StreamReader(f, emit_chunks=True, validate_crcs=True, record_size_limit=max(total, 1))
    for record in reader.records:
        end = f.tell()
        if isinstance(record, Chunk):
            for inner in breakup_chunk(record, validate_crc=True):
                yield inner, end
        else:
            yield record, end


def _reason(exc: BaseException) -> str:
    if isinstance(exc, CRCValidationError):
        return f"CRC mismatch: {exc}"
    name = type(exc).__name__
    text = str(exc)
    if name == "EndOfFile":
        return "file ends in the middle of a record or without a footer"
    return f"{name}: {text}" if text else name


class RecordingReader:
    """Reader for one recording (see the module docstring).

    ``expected_profile``: a `Profile` or a profile name. A different profile name, or the same name
    with different decoding settings (code, camera, projector, decoder, edc, geometry), raises
    `ProfileMismatchError` naming the differing keys.
    """

    def __init__(self, path: str | os.PathLike[str], *, expected_profile: Profile | str | None = None,
                 strict: bool = True):
        self.path = os.fspath(path)
        self.strict = strict
        self.problem: str | None = None
        self.total_bytes = os.path.getsize(self.path)
        with open(self.path, "rb") as f:
            head = f.read(len(MCAP_MAGIC))
        if head != MCAP_MAGIC:
            raise NotMcapError(f"{self.path}: not an MCAP file (expected magic {MCAP_MAGIC!r}, "
                               f"got {head!r}, file size {self.total_bytes} bytes)")
        self._metadata: dict[str, dict[str, str]] = {}
        self._attachments: dict[str, bytes] = {}
        self._read_head()
        self.profile = self._load_profile()
        if expected_profile is not None:
            self.check_profile(expected_profile)

    # -- head: metadata before the first chunk -------------------------------------------------

    def _read_head(self) -> None:
        with open(self.path, "rb") as f:
            try:
                reader = StreamReader(f, emit_chunks=True, validate_crcs=False,
                                      record_size_limit=max(self.total_bytes, 1))
                for record in reader.records:
                    if isinstance(record, Metadata):
                        self._metadata[record.name] = dict(record.metadata)
                    elif isinstance(record, Attachment):
                        self._attachments[record.name] = bytes(record.data)
                    elif isinstance(record, (Chunk, Message)):
                        break
            except (McapError, struct.error, ValueError, EOFError):
                pass  # reported by the full pass

    def _load_profile(self) -> Profile | None:
        meta = self._metadata.get(PROFILE_METADATA)
        if meta is None or "json" not in meta:
            return None
        try:
            return profile_from_dict(json.loads(meta["json"]), source=f"{self.path} (recorded profile)")
        except (ValueError, ProfileError) as exc:
            raise RecordingError(f"{self.path}: recorded profile is invalid: {exc}") from None

    @property
    def sensor_metadata(self) -> dict[str, str]:
        return dict(self._metadata.get(SENSOR_METADATA, {}))

    @property
    def metadata(self) -> dict[str, dict[str, str]]:
        """Every metadata record found before the first chunk, by name."""
        return {k: dict(v) for k, v in self._metadata.items()}

    def check_profile(self, expected: Profile | str) -> None:
        """Raise `ProfileMismatchError` unless the recording was made with ``expected``."""
        name = expected if isinstance(expected, str) else expected.name
        if self.profile is None:
            raise ProfileMismatchError(f"{self.path}: has no recorded profile; expected profile {name!r}")
        if self.profile.name != name:
            raise ProfileMismatchError(
                f"{self.path}: recorded with profile {self.profile.name!r}, expected {name!r}")
        if isinstance(expected, Profile):
            diff = [k for k in changed_keys(self.profile, expected) if not k.startswith(_NOT_DECODING)]
            if diff:
                raise ProfileMismatchError(
                    f"{self.path}: recorded profile {name!r} differs from the expected one in "
                    f"{', '.join(diff[:6])}{' ...' if len(diff) > 6 else ''}")

    # -- summary ---------------------------------------------------------------------------------

    @property
    def summary(self) -> Any:
        """mcap's Summary (schemas, channels, statistics, chunk indexes) or None if not finalised."""
        try:
            with open(self.path, "rb") as f:
                return make_reader(f, validate_crcs=True).get_summary()
        except (McapError, struct.error, ValueError, EOFError, OSError):
            return None

    @property
    def complete(self) -> bool:
        """True if the file ends with a footer and a readable summary."""
        return self.summary is not None

    # -- messages --------------------------------------------------------------------------------

    def messages(self, topics: list[str] | None = None) -> Iterator[RecordedMessage]:
        """Every message in file order, decoded (see `RecordedMessage`); raises at a bad record."""
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        count, offset, last_time = 0, len(MCAP_MAGIC), None
        self.problem = None
        with open(self.path, "rb") as f:
            try:
                for record, end in scan_records(f, self.total_bytes):
                    if isinstance(record, Schema):
                        schemas[record.id] = record
                    elif isinstance(record, Channel):
                        channels[record.id] = record
                    elif isinstance(record, Message):
                        channel = channels[record.channel_id]
                        count += 1
                        last_time = record.log_time
                        if topics is None or channel.topic in topics:
                            schema = schemas.get(channel.schema_id)
                            yield RecordedMessage(channel.topic, record.log_time, record.sequence,
                                                  schema.name if schema else "",
                                                  _decode(schema, channel, record.data))
                    elif isinstance(record, Footer):
                        offset = end
                        break
                    offset = end
            except (McapError, struct.error, ValueError, EOFError, KeyError) as exc:
                pos = f"{offset} of {self.total_bytes}"
                when = f" (last log time {last_time} ns)" if last_time is not None else ""
                msg = (f"{self.path}: truncated or corrupt MCAP at byte {pos}: {_reason(exc)}; "
                       f"read {count} messages before it{when}")
                self.problem = msg
                if self.strict:
                    raise TruncatedRecordingError(msg, offset=offset, total=self.total_bytes,
                                                  messages=count) from None

    def frames(self) -> Iterator[RecordedFrame]:
        """Recorded camera frames in file order with their raw_info metadata."""
        infos: dict[int, dict[str, Any]] = {}
        for m in self.messages():
            leaf = m.topic.rsplit("/", 1)[-1]
            if leaf == "raw_info":
                infos[m.sequence] = m.value
            elif leaf == "raw":
                yield _frame(m, infos.pop(m.sequence, {}))

    def outputs(self) -> Iterator[RecordedOutput]:
        """Recorded depth / confidence pairs in file order."""
        for item in self._events():
            if isinstance(item, RecordedOutput):
                yield item

    def _events(self) -> Iterator[Any]:
        """RecordedFrame, RecordedOutput and ("stack", dict) items in file order."""
        infos: dict[int, dict[str, Any]] = {}
        out_info: dict[int, dict[str, Any]] = {}
        depth: dict[int, tuple[np.ndarray, int]] = {}
        for m in self.messages():
            leaf = m.topic.rsplit("/", 1)[-1]
            if leaf == "raw_info":
                infos[m.sequence] = m.value
            elif leaf == "raw":
                yield _frame(m, infos.pop(m.sequence, {}))
            elif leaf == "output_info":
                out_info[m.sequence] = m.value
            elif leaf == "depth":
                depth[m.sequence] = (m.value, m.log_time)
            elif leaf == "confidence" and m.sequence in depth:
                d, t = depth.pop(m.sequence)
                info = out_info.pop(m.sequence, {})
                yield RecordedOutput(d, m.value, int(info.get("timestamp_ns", t)),
                                     int(info.get("stack", -1)), int(m.sequence), info)
            elif leaf == "stack":
                yield ("stack", m.value)

    def stacks(self, *, max_pending: int = 16) -> Iterator[RecordedStack]:
        """Frames grouped by stack id, with the stack's info and recorded output attached.

        A stack is yielded once its output has arrived and a later stack's frames have started, or
        once frames of a stack ``max_pending`` ids later have been seen (outputs come from the
        decode thread, so they may lag the raw frames), or at the end of the file. Writers should
        call ``write_stack`` before ``write_depth`` for a stack so the info lands with it.
        """
        open_stacks: dict[int, RecordedStack] = {}
        newest = None

        def ready(s: RecordedStack) -> bool:
            return newest is not None and ((s.output is not None and s.stack < newest)
                                           or s.stack + max_pending <= newest)

        def flush(force: bool) -> Iterator[RecordedStack]:
            for sid in sorted(open_stacks):
                if force or ready(open_stacks[sid]):
                    yield open_stacks.pop(sid)

        for item in self._events():
            if isinstance(item, RecordedFrame):
                sid = item.stack
                newest = sid if newest is None else max(newest, sid)
            elif isinstance(item, RecordedOutput):
                sid = item.stack
                newest = sid if newest is None else max(newest, sid)
            else:
                sid = int(item[1].get("stack", -1))
            st = open_stacks.setdefault(sid, RecordedStack(sid, []))
            if isinstance(item, RecordedFrame):
                st.frames.append(item)
            elif isinstance(item, RecordedOutput):
                st.output = item
            else:
                st.info = item[1]
            yield from flush(False)
        yield from flush(True)


def _frame(m: RecordedMessage, info: dict[str, Any]) -> RecordedFrame:
    return RecordedFrame(image=m.value, sequence=int(info.get("sequence", m.sequence)),
                         timestamp_ns=int(info.get("timestamp_ns", m.log_time)),
                         stack=int(info.get("stack", -1)),
                         projector_frame=int(info.get("projector_frame", -1)),
                         exposure_us=float(info.get("exposure_us", 0.0)),
                         role=str(info.get("role", "pattern")), info=info)


def _decode(schema: Schema | None, channel: Channel, data: bytes) -> Any:
    if channel.message_encoding == "json":
        return json.loads(data)
    if channel.message_encoding == "protobuf" and schema is not None:
        if schema.name == "foxglove.RawImage":
            msg = RawImage()
            msg.ParseFromString(data)
            return raw_to_image(msg)
        if schema.name == "foxglove.CameraCalibration":
            msg = CameraCalibration()
            msg.ParseFromString(data)
            return msg
        if schema.name == "foxglove.PointCloud":
            from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud

            msg = PointCloud()
            msg.ParseFromString(data)
            return msg
        if schema.name == "foxglove.FrameTransforms":
            from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

            msg = FrameTransforms()
            msg.ParseFromString(data)
            return msg
    return bytes(data)

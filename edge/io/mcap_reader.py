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

Reading is one sequential pass over the records (file order, `edge.io.mcap_scan.RecordScanner`)
with every CRC validated (chunks, data section, summary), both magics and the end of the file
checked. A corrupt chunk is skipped (``reader.chunks_skipped``) and reading goes on with the next
valid one; a truncated or corrupt file yields everything readable, then raises
`TruncatedRecordingError` naming the byte offset of the first problem and what was read
(``strict=False``: end quietly and leave the message in ``reader.problem``, every problem in
``reader.problems``). The recorded profile's sha256 is checked on open. A non-MCAP file raises
`NotMcapError`, a directory or unreadable path `RecordingError`. All errors are
`RecordingError`, a ValueError, with one line of text.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from google.protobuf.message import DecodeError
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Message, Metadata, Schema

from edge.profiles import Profile, ProfileError, changed_keys, profile_from_dict

from .mcap_format import PROFILE_METADATA, RECORDING_METADATA, SENSOR_METADATA, raw_to_image
from .mcap_scan import CORRUPT_ERRORS, MCAP_MAGIC, RecordScanner, describe_error, summary_definitions

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

# Profile sections that do not change what the decoder computes (ignored by the profile check).
_NOT_DECODING = ("description", "sensor.", "zenoh.", "recording.", "sim.")


#: How many stack ids a recorded depth map may trail its frames by before `RecordingReader.stacks`
#: gives up waiting for it: the service's largest queue (``edge run --queue``, 64), the stack in
#: decode and slack.  Every stack the service drops is marked in newer recordings, so this bound
#: only matters for older ones and for a service that stopped mid-stack.
MAX_PENDING = 72


def stack_complete(stack: int, has_output: bool, dropped: bool, newest: int | None, max_pending: int) -> bool:
    """Whether a recorded stack can be handed on (`RecordingReader.stacks`, `edge.io.event_record.event_stacks`):
    the service marked it dropped, or its output arrived and a later stack started (``newest``: the
    largest stack id seen), or a stack ``max_pending`` ids later was seen."""
    return dropped or newest is not None and ((has_output and stack < newest) or stack + max_pending <= newest)


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
    error: np.ndarray | None = None  # (H, W) float32 P(wrong), NaN = no estimate; None if not recorded


@dataclass
class RecordedStack:
    stack: int
    frames: list[RecordedFrame]
    info: dict[str, Any] | None = None       # the /stack message, if recorded
    output: RecordedOutput | None = None     # the recorded depth / confidence, if any
    dropped: str | None = None               # why the service did not decode it ("stale", ...), if recorded

    @property
    def images(self) -> np.ndarray:
        """(n, H, W) frames of the stack in recorded order."""
        return np.stack([f.image for f in self.frames])


def scan_records(f: io.BufferedReader, total: int) -> Iterator[tuple[Any, int]]:
    """Yield ``(record, end_offset)`` for every record in file order, chunks broken up.

    ``end_offset`` is the byte offset just past the top-level record the item came from (for a
    chunk's inner records: the end of the chunk). Every CRC is checked (`RecordScanner`); the first
    problem raises `TruncatedRecordingError` after everything readable was yielded.
    """
    scan = RecordScanner(f, total)
    yield from scan
    if scan.problems:
        offset, reason, count = scan.problems[0]
        raise TruncatedRecordingError(f"truncated or corrupt MCAP at byte {offset} of {total}: {reason}",
                                      offset=offset, total=total, messages=count)


def _reason(exc: BaseException) -> str:
    return describe_error(exc)


#: The decoder settings of a recording made before profiles had ``decoder.validity`` (before the
#: error-probability rule existed): what its service decoded with, for the keys it does not store.
PRE_VALIDITY_DECODER = {"validity": "confidence", "levels": "calibration"}


def recorded_profile_dict(data: Any) -> Any:
    """A recorded profile's dict as it decodes: every recording stores every key of its time
    (`edge.profiles.profile_to_dict`), so one whose ``decoder`` table has no ``validity`` predates
    the error-probability rule and decoded with `PRE_VALIDITY_DECODER` (filled in where absent;
    keys added since keep their defaults, which are what it used).  Other dicts come back as given."""
    if isinstance(data, dict) and isinstance(data.get("decoder"), dict) and "validity" not in data["decoder"]:
        data = {**data, "decoder": {**PRE_VALIDITY_DECODER, **data["decoder"]}}
    return data


class OutputPairs:
    """Pairs a recording's ``output_info`` / ``depth`` / (optional) ``error`` / ``confidence``
    messages of one sequence number into a `RecordedOutput` (the writer puts them in that order;
    ``output_info`` may be missing: the depth message's log time is the timestamp then)."""

    def __init__(self) -> None:
        self._info: dict[int, dict[str, Any]] = {}
        self._depth: dict[int, tuple[np.ndarray, int]] = {}
        self._error: dict[int, np.ndarray] = {}

    def take(self, leaf: str, m: Any) -> RecordedOutput | None:
        """Feed one message (``leaf``: the last part of its topic); the output it completes, or None."""
        if leaf == "output_info":
            self._info[m.sequence] = m.value
        elif leaf == "depth":
            self._depth[m.sequence] = (m.value, m.log_time)
            self._error.pop(m.sequence, None)
        elif leaf == "error" and m.sequence in self._depth:
            self._error[m.sequence] = m.value
        elif leaf == "confidence" and m.sequence in self._depth:
            d, t = self._depth.pop(m.sequence)
            info = self._info.pop(m.sequence, {})
            return RecordedOutput(d, m.value, int(info.get("timestamp_ns", t)), int(info.get("stack", -1)),
                                  int(m.sequence), info, error=self._error.pop(m.sequence, None))
        return None


def refuse_folder(path: str) -> None:
    """RecordingError ``"PATH: is a folder, expected an MCAP recording file"`` where the recording
    to read, ``path``, is a folder (the readers' and `recover`'s one wording)."""
    if os.path.isdir(path):
        raise RecordingError(f"{path}: is a folder, expected an MCAP recording file")


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
        self.problems: list[str] = []       # every problem of the last pass, first one in ``problem``
        self.chunks_skipped = 0             # corrupt chunks skipped in the last pass
        self.leaves_seen: set[str] = set()  # topics' last parts seen by the last frames / outputs / stacks pass
        self.head_problem: str | None = None  # the first problem before the first message, if any
        refuse_folder(self.path)
        try:
            self.total_bytes = os.path.getsize(self.path)
            with open(self.path, "rb") as f:
                head = f.read(len(MCAP_MAGIC))
        except FileNotFoundError:
            raise RecordingError(f"{self.path}: no such recording") from None
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot read the recording: {exc.strerror or exc}") from None
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
            scan = RecordScanner(f, self.total_bytes, head_only=True)
            for record, _ in scan:
                if isinstance(record, Metadata):
                    self._metadata[record.name] = dict(record.metadata)
                elif isinstance(record, Attachment):
                    self._attachments[record.name] = bytes(record.data)
                elif isinstance(record, Message):
                    break
            # problems are reported by the full pass; the head's first one is kept for a file that
            # ends before its metadata (`head_problem`)
            if scan.problems:
                offset, reason = scan.problems[0][:2]
                self.head_problem = (f"{self.path}: truncated or corrupt MCAP at byte {offset} of "
                                     f"{self.total_bytes}: {reason}")

    def _load_profile(self) -> Profile | None:
        meta = self._metadata.get(PROFILE_METADATA)
        if meta is None or "json" not in meta:
            return None
        digest = meta.get("sha256")
        if digest is not None and hashlib.sha256(meta["json"].encode()).hexdigest() != digest:
            raise RecordingError(f"{self.path}: recorded profile fails its sha256 check "
                                 f"(the profile metadata is corrupt); cannot trust this recording")
        try:
            return profile_from_dict(recorded_profile_dict(json.loads(meta["json"])),
                                     source=f"{self.path} (recorded profile)")
        except (ValueError, ProfileError) as exc:
            raise RecordingError(f"{self.path}: recorded profile is invalid: {exc}") from None

    @property
    def format(self) -> int:
        """The recording format (`edge.io.mcap_format.RECORDING_FORMAT`; 1 for a recording without the
        record, made before it existed)."""
        try:
            return int(self._metadata.get(RECORDING_METADATA, {}).get("format", 1))
        except ValueError:
            return 1

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
        """mcap's Summary (schemas, channels, statistics, chunk indexes) or None if not finalised.

        Parsed (CRCs checked) once per state of the file: the result is kept while the file's size,
        modification time and inode stay the same, so `summary` and `complete` cost one parse."""
        try:
            st = os.stat(self.path)
        except OSError:
            return None
        key = (st.st_size, st.st_mtime_ns, st.st_ino)
        cached = getattr(self, "_summary_cache", None)
        if cached is not None and cached[0] == key:
            return cached[1]
        try:
            with open(self.path, "rb") as f:
                summary = make_reader(f, validate_crcs=True).get_summary()
        except (*CORRUPT_ERRORS, OSError):
            summary = None
        self._summary_cache = (key, summary)
        return summary

    @property
    def complete(self) -> bool:
        """True if the file ends with a footer and a readable summary."""
        return self.summary is not None

    # -- messages --------------------------------------------------------------------------------

    def messages(self, topics: list[str] | None = None) -> Iterator[RecordedMessage]:
        """Every message in file order, decoded (see `RecordedMessage`).

        Corrupt chunks are skipped (counted in ``chunks_skipped``) and reading goes on with the next
        valid one; at the end, the first problem raises `TruncatedRecordingError` (``strict``) or is
        left in ``problem``."""
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        count, last_time = 0, None
        bad: list[tuple[int, str, int, int | None]] = []  # (offset, reason, messages before, last time)
        self.problem, self.problems, self.chunks_skipped = None, [], 0
        with open(self.path, "rb") as f:
            spare_schemas, spare_channels = summary_definitions(f)  # if the defining chunk is corrupt
            scan = RecordScanner(f, self.total_bytes)
            seen = 0
            for record, end in scan:
                while seen < len(scan.problems):
                    bad.append((*scan.problems[seen][:2], count, last_time))
                    seen += 1
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    channel = channels.get(record.channel_id) or spare_channels.get(record.channel_id)
                    if channel is not None and channel.schema_id not in schemas \
                            and channel.schema_id in spare_schemas:
                        schemas[channel.schema_id] = spare_schemas[channel.schema_id]
                    if channel is None:
                        bad.append((end, f"message on unknown channel {record.channel_id}", count, last_time))
                        continue
                    if topics is not None and channel.topic not in topics:
                        count += 1
                        last_time = record.log_time
                        continue
                    schema = schemas.get(channel.schema_id)
                    try:
                        value = _decode(schema, channel, record.data)
                    except (*CORRUPT_ERRORS, DecodeError) as exc:
                        bad.append((end, f"undecodable message on {channel.topic}: {describe_error(exc)}",
                                    count, last_time))
                        continue
                    count += 1
                    last_time = record.log_time
                    yield RecordedMessage(channel.topic, record.log_time, record.sequence,
                                          schema.name if schema else "", value)
            bad += [(*p[:2], count, last_time) for p in scan.problems[seen:]]
            self.chunks_skipped = scan.chunks_skipped
        if bad:
            self.problems = [f"byte {o}: {r}" for o, r, _, _ in bad]
            offset, reason, before, when_ns = bad[0]
            when = f" (last log time {when_ns} ns)" if when_ns is not None else ""
            msg = (f"{self.path}: truncated or corrupt MCAP at byte {offset} of {self.total_bytes}: {reason}; "
                   f"read {before} messages before it{when}")
            if len(bad) > 1 or count > before:
                msg += (f"; {len(bad) - 1} more problem(s) after it, {scan.chunks_skipped} corrupt chunk(s) "
                        f"skipped, {count} messages read in all")
            self.problem = msg
            if self.strict:
                raise TruncatedRecordingError(msg, offset=offset, total=self.total_bytes, messages=before)

    def frames(self) -> Iterator[RecordedFrame]:
        """Recorded camera frames in file order with their raw_info metadata."""
        for item in self._events():
            if isinstance(item, RecordedFrame):
                yield item

    def outputs(self) -> Iterator[RecordedOutput]:
        """Recorded outputs (depth, confidence and the error probability where recorded) in file order."""
        for item in self._events():
            if isinstance(item, RecordedOutput):
                yield item

    def _events(self) -> Iterator[Any]:
        """RecordedFrame, RecordedOutput and ("stack", dict) items in file order (the topics' last
        parts seen so far are in ``leaves_seen``)."""
        infos: dict[int, dict[str, Any]] = {}
        outputs = OutputPairs()
        self.leaves_seen.clear()
        for m in self.messages():
            leaf = m.topic.rsplit("/", 1)[-1]
            self.leaves_seen.add(leaf)
            if leaf == "raw_info":
                infos[m.sequence] = m.value
            elif leaf == "raw":
                yield _frame(m, infos.pop(m.sequence, {}))
            elif leaf == "stack":
                yield ("stack", m.value)
            else:
                out = outputs.take(leaf, m)
                if out is not None:
                    yield out

    def stacks(self, *, max_pending: int = MAX_PENDING) -> Iterator[RecordedStack]:
        """Frames grouped by stack id, with the stack's info and recorded output attached.

        A stack is yielded once its output has arrived and a later stack's frames have started, or
        once the service recorded that it dropped it (``dropped``), or once frames of a stack
        ``max_pending`` ids later have been seen (outputs come from the decode thread, so they lag
        the raw frames by up to the service's queue), or at the end of the file. Writers should
        call ``write_stack`` before ``write_depth`` for a stack so the info lands with it.
        """
        open_stacks: dict[int, RecordedStack] = {}
        newest = None

        def ready(s: RecordedStack) -> bool:
            return stack_complete(s.stack, s.output is not None, s.dropped is not None, newest, max_pending)

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
            elif "dropped" in item[1]:
                st.dropped = str(item[1]["dropped"])
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

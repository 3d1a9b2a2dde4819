"""`recover(path, out_path)`: salvage a recording whose writer died without ``finish()``.

A SIGKILLed writer leaves the header, metadata, attachments and every chunk it completed, then
possibly part of a chunk, and no summary or footer. `recover` reads the file record by record
(`RecordScanner`: every CRC checked), skips a corrupt chunk (counted in ``chunks_skipped``) and goes
on with the next valid one, stops at the end of the readable data, and writes everything readable
(schemas, channels, messages, metadata, attachments) into a new, finalised MCAP file with the same
chunk compression. It returns a `RecoveryReport`; a file that is fine is simply copied
record by record (``report.complete_input`` is True). Non-MCAP input raises `NotMcapError`; a
damaged file without a single readable message (cut inside its first chunk) raises
`RecordingError` and nothing is written.
"""

from __future__ import annotations

import contextlib
import json
import os
import uuid
from dataclasses import dataclass, field
from typing import BinaryIO

from mcap.records import Attachment, Channel, Chunk, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from .mcap_format import MCAP_PROFILE
from .mcap_reader import NotMcapError, RecordingError, refuse_folder
from .mcap_scan import CORRUPT_ERRORS, MCAP_MAGIC, RecordScanner, summary_definitions
from .paths import check_not_folder, write_target

__all__ = ["RecoveryReport", "recover"]

_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}


@dataclass
class RecoveryReport:
    path: str
    out_path: str
    total_bytes: int            # size of the damaged input
    recovered_bytes: int        # input bytes up to the end of the last complete record
    chunks: int                 # complete chunks copied
    messages: int
    topics: dict[str, int] = field(default_factory=dict)   # messages per topic
    stacks: list[int] = field(default_factory=list)        # stack ids seen in raw_info messages
    first_log_time: int | None = None
    last_log_time: int | None = None
    complete_input: bool = False  # the input had a footer and no problem (nothing was lost)
    reason: str = ""              # the first problem found (why reading stopped, if it stopped early)
    chunks_skipped: int = 0       # corrupt chunks skipped (their messages are lost)
    bytes_skipped: int = 0        # input bytes skipped over corrupt records
    problems: int = 0             # problems found in all

    def __str__(self) -> str:
        head = (f"recovered {self.messages} messages in {self.chunks} chunks "
                f"({self.recovered_bytes} of {self.total_bytes} bytes) from {self.path} into {self.out_path}")
        if self.complete_input:
            return head + "; the input was complete"
        topics = ", ".join(f"{t}: {n}" for t, n in sorted(self.topics.items()))
        lost = self.total_bytes - self.recovered_bytes
        skipped = (f"; {self.chunks_skipped} corrupt chunk(s) skipped ({self.bytes_skipped} bytes), "
                   f"{self.problems} problem(s) in all" if self.chunks_skipped or self.problems > 1 else "")
        return (f"{head}; {lost} trailing bytes dropped ({self.reason}){skipped}; "
                f"per topic: {topics or 'none'}")


def recover(path: str | os.PathLike[str], out_path: str | os.PathLike[str], *,
            chunk_size: int = 4 * 1024 * 1024) -> RecoveryReport:
    """Copy the readable part of ``path`` into a finalised MCAP at ``out_path``; see the module doc.

    The output is written to a temporary file next to ``out_path`` and renamed onto it at the end,
    so ``out_path`` is never left half-written (where ``out_path`` is a symbolic link, next to and
    onto the file it leads to: the link stays).  An incomplete input from which no message could be
    read (cut inside its first chunk, only a header) raises `RecordingError` and writes nothing:
    an empty "recovered" file would pass for a salvage of the recording.
    """
    path, out_path = os.fspath(path), os.fspath(out_path)
    if os.path.abspath(path) == os.path.abspath(out_path) or (
            os.path.exists(out_path) and os.path.exists(path) and os.path.samefile(path, out_path)):
        # also a symlink or hard link to the input: writing it would truncate the input
        raise ValueError(f"expected an output path different from the input, got {out_path!r}, "
                         f"which is {path!r} itself (same file); nothing was written")
    refuse_folder(path)
    try:
        check_not_folder(out_path, option="output")
    except ValueError as exc:
        raise RecordingError(str(exc)) from None
    total = os.path.getsize(path)
    with open(path, "rb") as f:
        head = f.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC:
        raise NotMcapError(f"{path}: not an MCAP file (expected magic {MCAP_MAGIC!r}, got {head!r})")

    report = RecoveryReport(path=path, out_path=out_path, total_bytes=total,
                            recovered_bytes=len(MCAP_MAGIC), chunks=0, messages=0)
    target = write_target(out_path)  # a symbolic link stays one: the file it leads to is replaced
    partial = os.path.join(os.path.dirname(os.path.abspath(target)),
                           f".edge-recover-{os.getpid()}-{uuid.uuid4().hex[:8]}.part")
    try:
        with open(partial, "xb") as out:
            _copy_readable(path, out, report, chunk_size)
        if report.messages == 0 and not report.complete_input:
            raise RecordingError(f"{path}: nothing could be recovered: no complete chunk holds a message "
                                 f"({report.reason or 'no chunk at all'}); nothing was written")
        os.replace(partial, target)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(partial)
    return report


def _header_and_compression(path: str, total: int) -> tuple[str, str, CompressionType]:
    """(profile, library) of the input's header and the compression of its first chunk, without
    writing anything; defaults where the file holds no header or no readable chunk."""
    compression, header_profile, library = CompressionType.ZSTD, MCAP_PROFILE, "edge recover"
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f, emit_chunks=True, record_size_limit=max(total, 1)).records:
                if isinstance(record, Header):
                    header_profile, library = record.profile, record.library or library
                if isinstance(record, Chunk):
                    compression = _COMPRESSION.get(record.compression, CompressionType.ZSTD)
                    break
        except CORRUPT_ERRORS:
            pass
    return header_profile, library, compression


def _copy_readable(path: str, out: BinaryIO, report: RecoveryReport, chunk_size: int) -> None:
    """Write every readable record of ``path`` into ``out`` as a finalised MCAP; fill ``report``."""
    header_profile, library, compression = _header_and_compression(path, report.total_bytes)
    schema_map: dict[int, int] = {}
    channel_map: dict[int, int] = {}
    topics_by_id: dict[int, str] = {}
    stacks: set[int] = set()
    with open(path, "rb") as f:
        writer = Writer(out, chunk_size=chunk_size, compression=compression, enable_crcs=True,
                        enable_data_crcs=True)
        writer.start(profile=header_profile, library=library)
        spare_schemas, spare_channels = summary_definitions(f)  # if the defining chunk is corrupt
        scan = RecordScanner(f, report.total_bytes)
        try:
            for record, end in scan:
                if isinstance(record, Footer):
                    report.complete_input = not scan.problems
                    report.recovered_bytes = report.total_bytes
                    break
                if isinstance(record, (Schema, Channel, Message, Metadata, Attachment)):
                    if isinstance(record, Message) and record.channel_id not in channel_map \
                            and record.channel_id in spare_channels:
                        channel = spare_channels[record.channel_id]
                        if channel.schema_id in spare_schemas:
                            _copy(writer, spare_schemas[channel.schema_id], schema_map, channel_map,
                                  topics_by_id, report, stacks)
                        _copy(writer, channel, schema_map, channel_map, topics_by_id, report, stacks)
                    try:
                        _copy(writer, record, schema_map, channel_map, topics_by_id, report, stacks)
                    except KeyError:  # a message of a channel lost in a skipped chunk
                        continue
                report.recovered_bytes = end
            report.chunks = scan.chunks_ok
        finally:
            writer.finish()
    report.chunks_skipped, report.bytes_skipped = scan.chunks_skipped, scan.bytes_skipped
    report.problems = len(scan.problems)
    if scan.problems:
        offset, reason, _ = scan.problems[0]
        report.reason = reason if f"byte {offset}" in reason else f"{reason} at byte {offset}"
    report.stacks = sorted(stacks)


def _copy(writer: Writer, r: object, schema_map: dict[int, int], channel_map: dict[int, int],
          topics_by_id: dict[int, str], report: RecoveryReport, stacks: set[int]) -> None:
    if isinstance(r, Schema):
        if r.id not in schema_map:
            schema_map[r.id] = writer.register_schema(r.name, r.encoding, r.data)
    elif isinstance(r, Channel):
        if r.id not in channel_map:
            channel_map[r.id] = writer.register_channel(r.topic, r.message_encoding,
                                                        schema_map.get(r.schema_id, 0), dict(r.metadata))
            topics_by_id[r.id] = r.topic
    elif isinstance(r, Message):
        writer.add_message(channel_map[r.channel_id], r.log_time, r.data, r.publish_time, r.sequence)
        topic = topics_by_id[r.channel_id]
        report.messages += 1
        report.topics[topic] = report.topics.get(topic, 0) + 1
        if report.first_log_time is None:
            report.first_log_time = r.log_time
        report.last_log_time = r.log_time
        if topic.endswith("/raw_info"):
            try:
                stacks.add(int(json.loads(r.data).get("stack", -1)))
            except (ValueError, AttributeError):
                pass
    elif isinstance(r, Metadata):
        writer.add_metadata(r.name, dict(r.metadata))
    elif isinstance(r, Attachment):
        writer.add_attachment(r.create_time, r.log_time, r.name, r.media_type, r.data)

"""`finalize_in_place(path, end)`: turn the first ``end`` bytes of an unfinished MCAP file into a
finalised recording, in place, without a second copy.

When the disk fills up (ENOSPC, EFBIG) in the middle of a recording, `edge.io.mcap.recover` cannot
help: it writes a new file, which needs as much free space again.  But the writer knows the byte
offset where its last complete write ended (`edge.io.mcap_writer.Recorder` tracks it after every
flush), so the file can be cut back to that offset (freeing the half-written chunk) and completed
with a data-end record, a summary (schemas, channels, statistics, chunk / attachment / metadata
indexes, summary offsets) and the footer.  The summary is rebuilt by reading the kept records back
(chunk CRCs checked), so it describes exactly what is on disk.  It needs a few kilobytes.
"""

from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass, field

from mcap.data_stream import RecordBuilder
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import (Attachment, AttachmentIndex, Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Message,
                          MessageIndex, Metadata, MetadataIndex, Schema, Statistics, SummaryOffset)
from mcap.stream_reader import StreamReader, breakup_chunk

from .mcap_reader import MCAP_MAGIC, NotMcapError

__all__ = ["FinalizeReport", "finalize_in_place"]


@dataclass
class FinalizeReport:
    path: str
    kept_bytes: int                 # data bytes kept (the file was cut back to this offset)
    cut_bytes: int                  # bytes removed after it (a half-written chunk)
    chunks: int = 0
    messages: int = 0
    topics: dict[str, int] = field(default_factory=dict)   # messages per topic in the finalised file
    reason: str = ""                # why reading stopped before ``kept_bytes`` (normally empty)


def finalize_in_place(path: str | os.PathLike[str], end: int) -> FinalizeReport:
    """Cut ``path`` back to ``end`` bytes (the end of its last complete record) and append a summary
    and footer; see the module docstring.  Raises OSError if even that cannot be written (the cut
    file is then left for `edge.io.mcap.recover`), `NotMcapError` for a non-MCAP file."""
    path = os.fspath(path)
    total = os.path.getsize(path)
    end = max(len(MCAP_MAGIC), min(int(end), total))
    with open(path, "r+b") as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise NotMcapError(f"{path}: not an MCAP file")
        f.truncate(end)
        f.seek(0)
        report = FinalizeReport(path, end, total - end)
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        chunk_indexes: list[ChunkIndex] = []
        attachment_indexes: list[AttachmentIndex] = []
        metadata_indexes: list[MetadataIndex] = []
        counts: dict[int, int] = {}
        times: list[int] = []
        good = len(MCAP_MAGIC)
        try:
            reader = StreamReader(f, skip_magic=False, emit_chunks=True, validate_crcs=True,
                                  record_size_limit=max(end, 1))
            start = len(MCAP_MAGIC)
            for record in reader.records:
                stop = f.tell()
                if isinstance(record, (Footer, DataEnd)):
                    break
                if isinstance(record, Schema):
                    schemas.setdefault(record.id, record)
                elif isinstance(record, Channel):
                    channels.setdefault(record.id, record)
                elif isinstance(record, Chunk):
                    first = last = None
                    for r in breakup_chunk(record, validate_crc=True):
                        if isinstance(r, Schema):
                            schemas.setdefault(r.id, r)
                        elif isinstance(r, Channel):
                            channels.setdefault(r.id, r)
                        elif isinstance(r, Message):
                            counts[r.channel_id] = counts.get(r.channel_id, 0) + 1
                            first = r.log_time if first is None else min(first, r.log_time)
                            last = r.log_time if last is None else max(last, r.log_time)
                    if first is not None:
                        times += [first, last]
                    chunk_indexes.append(ChunkIndex(
                        message_start_time=record.message_start_time, message_end_time=record.message_end_time,
                        chunk_start_offset=start, chunk_length=stop - start, message_index_offsets={},
                        message_index_length=0, compression=record.compression,
                        compressed_size=len(record.data), uncompressed_size=record.uncompressed_size))
                    report.chunks += 1
                elif isinstance(record, Message):
                    counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
                    times += [record.log_time, record.log_time]
                elif isinstance(record, Attachment):
                    attachment_indexes.append(AttachmentIndex(
                        offset=start, length=stop - start, log_time=record.log_time,
                        create_time=record.create_time, data_size=len(record.data), name=record.name,
                        media_type=record.media_type))
                elif isinstance(record, Metadata):
                    metadata_indexes.append(MetadataIndex(offset=start, length=stop - start, name=record.name))
                elif isinstance(record, MessageIndex) and chunk_indexes:
                    ci = chunk_indexes[-1]
                    ci.message_index_offsets[record.channel_id] = start
                    ci.message_index_length = stop - (ci.chunk_start_offset + ci.chunk_length)
                elif not isinstance(record, Header):
                    pass
                good = start = stop
                if stop >= end:
                    break
        except (McapError, struct.error, ValueError, EOFError) as exc:
            report.reason = f"{type(exc).__name__}: {exc}"
        if good < end:  # a damaged record before ``end``: keep only what read back cleanly
            f.truncate(good)
            report.cut_bytes += end - good
            report.kept_bytes = good
            chunk_indexes = [c for c in chunk_indexes if c.chunk_start_offset + c.chunk_length <= good]
        f.seek(good)
        f.write(_summary(f, good, schemas, channels, chunk_indexes, attachment_indexes, metadata_indexes,
                         counts, times))
        f.flush()
        os.fsync(f.fileno())
    report.messages = sum(counts.values())
    report.topics = {channels[c].topic if c in channels else str(c): n for c, n in counts.items()}
    return report


def _summary(f, data_end: int, schemas, channels, chunk_indexes, attachment_indexes, metadata_indexes,
             counts, times) -> bytes:
    """DataEnd + summary section + footer + magic for a data section ending at ``data_end``."""
    f.seek(0)
    crc = 0  # the data-section CRC covers everything before DataEnd, magic included
    remaining = data_end
    while remaining > 0:
        block = f.read(min(remaining, 1 << 20))
        if not block:
            break
        crc = zlib.crc32(block, crc)
        remaining -= len(block)
    head = RecordBuilder()
    DataEnd(crc).write(head)
    head_bytes = head.end()
    summary_start = data_end + len(head_bytes)
    b = RecordBuilder()
    offsets: list[SummaryOffset] = []

    def group(opcode: int, records) -> None:
        records = list(records)
        if not records:
            return
        start = b.count
        for r in records:
            r.write(b)
        offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + start,
                                     group_length=b.count - start))

    group(Opcode.SCHEMA, schemas.values())
    group(Opcode.CHANNEL, channels.values())
    group(Opcode.STATISTICS, [Statistics(
        attachment_count=len(attachment_indexes), channel_count=len(channels),
        channel_message_counts=dict(counts), chunk_count=len(chunk_indexes), message_count=sum(counts.values()),
        message_end_time=max(times) if times else 0, message_start_time=min(times) if times else 0,
        metadata_count=len(metadata_indexes), schema_count=len(schemas))])
    group(Opcode.CHUNK_INDEX, chunk_indexes)
    group(Opcode.ATTACHMENT_INDEX, attachment_indexes)
    group(Opcode.METADATA_INDEX, metadata_indexes)
    summary_offset_start = summary_start + b.count
    for o in offsets:
        o.write(b)
    summary = b.end()
    summary_crc = zlib.crc32(summary)
    summary_crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start, summary_offset_start),
                             summary_crc)
    tail = RecordBuilder()
    Footer(summary_start=summary_start, summary_offset_start=summary_offset_start, summary_crc=summary_crc).write(tail)
    return head_bytes + summary + tail.end() + MCAP_MAGIC

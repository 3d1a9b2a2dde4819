"""`RecordScanner`: walk an MCAP file record by record, check every CRC, and skip what is corrupt.

The mcap library's readers stop at the first bad byte (and raise whatever the decompressor raises:
``zstandard.ZstdError``, ``CRCValidationError``, ``struct.error`` ...).  The scanner instead:

* checks the magic at both ends, every chunk CRC, the data-section CRC (DataEnd), the summary CRC
  (Footer) and that the file ends right after the closing magic;
* skips a record whose framing is intact but whose content is corrupt (a chunk with a CRC or
  decompression error, a metadata record that does not parse), and goes on with the next record;
* after a broken record length (flipped bytes in a record header, zeroed regions) re-synchronises
  on the next chunk whose CRC checks, so one bad chunk loses only its own messages;
* records every problem as ``(byte offset, reason, messages yielded before it)`` in ``problems``,
  never raising for bad content (only OSError for an unreadable file).

Usage::

    scan = RecordScanner(f, total_bytes)
    for record, end in scan:          # mcap records (chunks broken up into their inner records)
        ...
    scan.problems, scan.chunks_ok, scan.chunks_skipped, scan.bytes_skipped, scan.footer_seen
"""

from __future__ import annotations

import io
import mmap
import re
import struct
import zlib
from typing import Any, BinaryIO, Iterator

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import CRCValidationError, breakup_chunk

__all__ = ["RecordScanner", "CORRUPT_ERRORS", "MCAP_MAGIC", "describe_error", "summary_definitions"]

MCAP_MAGIC = b"\x89MCAP0\r\n"

try:  # the decompressors' own error types escape mcap's breakup_chunk
    from zstandard import ZstdError as _ZstdError
except ImportError:  # pragma: no cover - zstandard is a dependency of mcap[zstd]
    _ZstdError = McapError  # type: ignore[assignment,misc]

#: Exceptions that mean "these bytes are not a valid record" (never a bug of the caller).
CORRUPT_ERRORS: tuple[type[BaseException], ...] = (McapError, struct.error, ValueError, EOFError, KeyError,
                                                   IndexError, OverflowError, MemoryError, RuntimeError,
                                                   _ZstdError)

_READERS = {
    Opcode.ATTACHMENT: Attachment.read, Opcode.ATTACHMENT_INDEX: AttachmentIndex.read,
    Opcode.CHANNEL: Channel.read, Opcode.CHUNK: Chunk.read, Opcode.CHUNK_INDEX: ChunkIndex.read,
    Opcode.DATA_END: DataEnd.read, Opcode.FOOTER: Footer.read, Opcode.HEADER: Header.read,
    Opcode.MESSAGE_INDEX: MessageIndex.read, Opcode.METADATA: Metadata.read,
    Opcode.METADATA_INDEX: MetadataIndex.read, Opcode.SCHEMA: Schema.read,
    Opcode.STATISTICS: Statistics.read, Opcode.SUMMARY_OFFSET: SummaryOffset.read,
}
_HEAD = struct.Struct("<BQ")
# A chunk record header: opcode 0x06 and a length < 2**40 (its three high bytes are zero).
_CHUNK_HEAD = re.compile(rb"\x06[\s\S]{5}\x00\x00\x00")
_COMPRESSIONS = ("", "zstd", "lz4")


def describe_error(exc: BaseException) -> str:
    """One line naming what is wrong with a record, for any exception in `CORRUPT_ERRORS`."""
    if isinstance(exc, CRCValidationError):
        return f"CRC mismatch: {exc}"
    name = type(exc).__name__
    if name == "EndOfFile":
        return "file ends in the middle of a record or without a footer"
    if isinstance(exc, _ZstdError):
        return f"corrupt zstd data: {exc}"
    text = " ".join(str(exc).split())[:200]
    return f"{name}: {text}" if text else name


def summary_definitions(f: BinaryIO) -> tuple[dict[int, Schema], dict[int, Channel]]:
    """Schemas and channels by id from the file's summary section ({} when it has none or it is
    unreadable): the fallback when the chunk that defined them is corrupt."""
    try:
        from mcap.reader import make_reader

        f.seek(0)
        summary = make_reader(f).get_summary()
    except (*CORRUPT_ERRORS, OSError):
        return {}, {}
    if summary is None:
        return {}, {}
    return dict(summary.schemas), dict(summary.channels)


def _parse(opcode: int, content: bytes) -> Any:
    if opcode == Opcode.MESSAGE:
        return Message.read(ReadDataStream(io.BytesIO(content)), len(content))
    read = _READERS.get(opcode)
    if read is None:
        return None  # unknown record types are skipped (MCAP spec)
    stream = ReadDataStream(io.BytesIO(content))
    record = read(stream)
    if stream.count > len(content):  # pragma: no cover - ReadDataStream raises before this
        raise EOFError("record content shorter than its fields")
    return record


def _check_chunk(chunk: Chunk) -> list[Any]:
    if chunk.compression not in _COMPRESSIONS:
        raise ValueError(f"unknown chunk compression {chunk.compression[:20]!r}")
    # zstd cannot expand more than 32768:1 (128 KiB blocks of a few bytes): a larger size is a flipped field
    if chunk.compression == "zstd" and chunk.uncompressed_size > 65536 * len(chunk.data) + (1 << 20):
        raise ValueError(f"implausible uncompressed size {chunk.uncompressed_size} for "
                         f"{len(chunk.data)} compressed bytes")
    records = breakup_chunk(chunk, validate_crc=True)
    if chunk.uncompressed_crc == 0:
        raise ValueError("chunk has no CRC (recordings are written with CRCs)")
    return records


class RecordScanner:
    """Iterate ``(record, end_offset)`` over an open MCAP file; see the module docstring.

    ``f``: a binary file positioned anywhere (the scanner seeks); ``total``: its size in bytes;
    ``head_only``: stop at the first chunk or message (metadata before the data).
    """

    def __init__(self, f: BinaryIO, total: int, *, head_only: bool = False) -> None:
        self.f, self.total, self.head_only = f, int(total), head_only
        self.problems: list[tuple[int, str, int]] = []
        self.messages = 0
        self.chunks_ok = 0
        self.chunks_skipped = 0
        self.bytes_skipped = 0
        self.footer_seen = False
        self.chunk_offsets: list[tuple[int, int]] = []   # (start, length incl. opcode+length) of good chunks
        self._map: mmap.mmap | None = None

    # -- helpers ---------------------------------------------------------------------------
    def _problem(self, offset: int, reason: str) -> None:
        self.problems.append((int(offset), reason, self.messages))

    def _read(self, offset: int, n: int) -> bytes:
        self.f.seek(offset)
        return self.f.read(n)

    def _resync(self, start: int) -> int | None:
        """Offset of the next chunk at or after ``start`` whose framing and CRC check, or None."""
        if self._map is None:
            try:
                self._map = mmap.mmap(self.f.fileno(), 0, access=mmap.ACCESS_READ)
            except (ValueError, OSError, io.UnsupportedOperation):
                self.f.seek(0)
                self._map = self.f.read()  # type: ignore[assignment]
        data = self._map
        for m in _CHUNK_HEAD.finditer(data, start):  # type: ignore[arg-type]
            pos = m.start()
            length = _HEAD.unpack_from(data, pos)[1]
            if pos + 9 + length > self.total or length < 36:
                continue
            comp_len = struct.unpack_from("<I", data, pos + 9 + 28)[0]
            if comp_len > 4 or bytes(data[pos + 9 + 32:pos + 9 + 32 + comp_len]).decode("latin-1") not in _COMPRESSIONS:
                continue
            try:
                _check_chunk(_parse(Opcode.CHUNK, bytes(data[pos + 9:pos + 9 + length])))
            except CORRUPT_ERRORS:
                continue
            return pos
        return None

    def close(self) -> None:
        if isinstance(self._map, mmap.mmap):
            self._map.close()
        self._map = None

    # -- the scan --------------------------------------------------------------------------
    def __iter__(self) -> Iterator[tuple[Any, int]]:
        try:
            yield from self._scan()
        finally:
            self.close()

    def _scan(self) -> Iterator[tuple[Any, int]]:
        total = self.total
        if self._read(0, len(MCAP_MAGIC)) != MCAP_MAGIC:
            self._problem(0, "not an MCAP file (bad magic)")
            return
        pos = len(MCAP_MAGIC)
        crc = zlib.crc32(MCAP_MAGIC)
        crc_ok = True          # False once anything was skipped: the data-section CRC is moot then
        summary_start: int | None = None
        while True:
            head = self._read(pos, 9)
            if len(head) < 9:
                self._problem(pos, "file ends in the middle of a record or without a footer"
                              if len(head) else "file ends without a footer")
                return
            opcode, length = _HEAD.unpack(head)
            end = pos + 9 + length
            if end > total or (opcode == Opcode.FOOTER and length != 20):
                nxt = self._resync(pos + 1)
                if nxt is None:
                    self._problem(pos, "file ends in the middle of a record or without a footer"
                                  if end > total else f"malformed footer (length {length})")
                    return
                self._problem(pos, f"record at byte {pos} (opcode 0x{opcode:02x}) has a broken length; "
                                   f"skipped {nxt - pos} bytes to the next valid chunk at byte {nxt}")
                self.bytes_skipped += nxt - pos
                crc_ok = False
                pos = nxt
                continue
            content = self._read(pos + 9, length)
            if len(content) < length:  # pragma: no cover - the file shrank while reading
                self._problem(pos, "file ends in the middle of a record or without a footer")
                return
            try:
                record = _parse(opcode, content)
                inner = _check_chunk(record) if isinstance(record, Chunk) else None
            except CORRUPT_ERRORS as exc:
                what = "chunk" if opcode == Opcode.CHUNK else f"record (opcode 0x{opcode:02x})"
                self._problem(pos, f"corrupt {what} at byte {pos}: {describe_error(exc)}; skipped")
                if opcode == Opcode.CHUNK:
                    self.chunks_skipped += 1
                self.bytes_skipped += end - pos
                crc_ok = False
                pos = end
                continue
            if summary_start is None and opcode not in (Opcode.FOOTER,):
                crc_before = crc
                crc = zlib.crc32(content, zlib.crc32(head, crc))
            if isinstance(record, Chunk):
                if self.head_only:
                    return
                self.chunks_ok += 1
                self.chunk_offsets.append((pos, end - pos))
                for r in inner or ():
                    if isinstance(r, Message):
                        self.messages += 1
                    yield r, end
            elif isinstance(record, Message) and self.head_only:
                return
            elif isinstance(record, DataEnd):
                if crc_ok and record.data_section_crc not in (0, crc_before):
                    self._problem(pos, f"data section CRC mismatch (DataEnd says {record.data_section_crc:#010x}, "
                                       f"the bytes give {crc_before:#010x})")
                summary_start = end
                yield record, end
            elif isinstance(record, Footer):
                self._check_footer(record, pos, head, content)
                yield record, end
                return
            elif record is not None:
                if isinstance(record, Message):
                    self.messages += 1
                yield record, end
            pos = end

    def _check_footer(self, footer: Footer, pos: int, head: bytes, content: bytes) -> None:
        self.footer_seen = True
        end = pos + 9 + len(content)
        if footer.summary_crc:
            start = footer.summary_start or pos
            if start > pos:
                self._problem(pos, f"footer points its summary at byte {start}, past the footer")
            else:
                crc = zlib.crc32(self._read(start, pos - start))
                crc = zlib.crc32(content[:16], zlib.crc32(head, crc))
                if crc != footer.summary_crc:
                    self._problem(start, f"summary CRC mismatch (footer says {footer.summary_crc:#010x}, "
                                         f"the bytes give {crc:#010x})")
        tail = self._read(end, len(MCAP_MAGIC) + 1)
        if tail[:len(MCAP_MAGIC)] != MCAP_MAGIC:
            self._problem(end, f"closing magic missing or damaged after the footer (got {tail[:8]!r})")
        elif len(tail) > len(MCAP_MAGIC):
            extra = self.total - end - len(MCAP_MAGIC)
            self._problem(end + len(MCAP_MAGIC), f"{extra} unexpected bytes after the closing magic")

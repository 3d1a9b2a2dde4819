"""Raw events in an edge MCAP recording: topic ``/<device>/events``, one message per `EventSlice`.

Schema ``edge.EventSlice`` (protobuf, proto3, encoded in the channel's schema record as a
FileDescriptorSet, so Foxglove and ``mcap`` tools can decode it)::

    int64  timestamp_ns    = 1;   // host time the slice was delivered
    int64  sequence        = 2;   // slice counter (consecutive within a stack)
    int64  stack           = 3;   // stack (code period) id
    int64  projector_frame = 4;   // projector frame id (edge.sensors.base; slot = chip index)
    int64  t_start_us      = 5;   // the slice's window [t_start_us, t_end_us), sensor clock (us)
    int64  t_end_us        = 6;
    uint32 count           = 7;   // number of events
    uint32 width           = 8;   // sensor size (pixels)
    uint32 height          = 9;
    bytes  x               = 10;  // count x uint16 little-endian (pixel column)
    bytes  y               = 11;  // count x uint16 little-endian (pixel row)
    bytes  t               = 12;  // count x int64 little-endian (sensor microseconds)
    bytes  p               = 13;  // count x int8 (+1 brighter, -1 darker)
    double exposure_us     = 14;  // slice duration (us)

The events are stored column-wise (struct of arrays, in arrival order, unmodified) because the
chunk compressor (zstd / lz4) packs equal-typed columns far better than interleaved 13-byte
records; decoding is four ``np.frombuffer`` calls, and `parse_event_slice` gives back exactly the
`EVENT_DTYPE` array that was recorded, so replay reproduces depth bit for bit.  MCAP ``log_time``
is ``timestamp_ns`` and ``sequence`` the slice's sequence number.  The channel is registered with
`register_events_channel` (the Recorder's public ``register_channel`` / ``write_message`` API).
"""

from __future__ import annotations

import functools
from typing import Any, Iterator, NamedTuple

import numpy as np

from ..sensors.base import EventSlice
from .mcap_reader import MAX_PENDING, stack_complete

SCHEMA_NAME = "edge.EventSlice"
TOPIC_LEAF = "events"

_FIELDS = [  # name, number, protobuf type name
    ("timestamp_ns", 1, "TYPE_INT64"), ("sequence", 2, "TYPE_INT64"), ("stack", 3, "TYPE_INT64"),
    ("projector_frame", 4, "TYPE_INT64"), ("t_start_us", 5, "TYPE_INT64"), ("t_end_us", 6, "TYPE_INT64"),
    ("count", 7, "TYPE_UINT32"), ("width", 8, "TYPE_UINT32"), ("height", 9, "TYPE_UINT32"),
    ("x", 10, "TYPE_BYTES"), ("y", 11, "TYPE_BYTES"), ("t", 12, "TYPE_BYTES"), ("p", 13, "TYPE_BYTES"),
    ("exposure_us", 14, "TYPE_DOUBLE"),
]


@functools.lru_cache(maxsize=1)
def _schema() -> tuple[Any, bytes]:
    """(message class, serialized FileDescriptorSet) of edge.EventSlice."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    fdp = descriptor_pb2.FileDescriptorProto(name="edge/EventSlice.proto", package="edge", syntax="proto3")
    msg = fdp.message_type.add(name="EventSlice")
    for name, number, type_name in _FIELDS:
        msg.field.add(name=name, number=number, type=getattr(descriptor_pb2.FieldDescriptorProto, type_name),
                      label=descriptor_pb2.FieldDescriptorProto.LABEL_OPTIONAL)
    pool = descriptor_pool.DescriptorPool()
    pool.Add(fdp)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(SCHEMA_NAME))
    return cls, descriptor_pb2.FileDescriptorSet(file=[fdp]).SerializeToString()


def schema_data() -> bytes:
    """The serialized FileDescriptorSet of ``edge.EventSlice`` (the MCAP schema record's data)."""
    return _schema()[1]


def register_events_channel(recorder) -> int:
    """Register ``/<device>/events`` (``edge.EventSlice``, protobuf) on an `edge.io.mcap_writer.Recorder`
    through its public `register_channel`; returns the channel id for ``recorder.write_message``
    (idempotent)."""
    return recorder.register_channel(TOPIC_LEAF, SCHEMA_NAME, "protobuf", schema_data())


def event_slice_message(s: EventSlice, width: int, height: int) -> bytes:
    """Serialize one `EventSlice` (see module docstring)."""
    cls = _schema()[0]
    ev = np.asarray(s.events)
    return cls(timestamp_ns=int(s.timestamp_ns), sequence=int(s.sequence), stack=int(s.stack),
               projector_frame=int(s.projector_frame), t_start_us=int(s.t_start_us), t_end_us=int(s.t_end_us),
               count=int(ev.size), width=int(width), height=int(height),
               x=np.ascontiguousarray(ev["x"], "<u2").tobytes(), y=np.ascontiguousarray(ev["y"], "<u2").tobytes(),
               t=np.ascontiguousarray(ev["t"], "<i8").tobytes(), p=np.ascontiguousarray(ev["p"], "i1").tobytes(),
               exposure_us=float(s.exposure_us)).SerializeToString()


def parse_event_slice(data: bytes) -> EventSlice:
    """Inverse of `event_slice_message`; ValueError for a malformed message."""
    from edge.source.events import EVENT_DTYPE

    msg = _schema()[0]()
    try:
        msg.ParseFromString(bytes(data))
    except Exception as exc:  # protobuf's DecodeError
        raise ValueError(f"malformed {SCHEMA_NAME} message: {exc}") from None
    n = int(msg.count)
    if (len(msg.x), len(msg.y), len(msg.t), len(msg.p)) != (2 * n, 2 * n, 8 * n, n):
        raise ValueError(f"malformed {SCHEMA_NAME} message: count {n} does not match the column sizes "
                         f"{len(msg.x)}, {len(msg.y)}, {len(msg.t)}, {len(msg.p)} bytes")
    ev = np.empty(n, EVENT_DTYPE)
    ev["x"] = np.frombuffer(msg.x, "<u2")
    ev["y"] = np.frombuffer(msg.y, "<u2")
    ev["t"] = np.frombuffer(msg.t, "<i8")
    ev["p"] = np.frombuffer(msg.p, "i1")
    return EventSlice(ev, int(msg.sequence), int(msg.timestamp_ns), float(msg.exposure_us), int(msg.projector_frame),
                      int(msg.stack), int(msg.t_start_us), int(msg.t_end_us))


class RecordedEventStack(NamedTuple):
    """One stack of an event recording (`event_stacks`)."""

    stack: int
    slices: list  #: its `EventSlice` records in file order
    output: Any = None  #: its `edge.io.mcap_reader.RecordedOutput`, or None
    info: dict | None = None  #: its ``/<device>/stack`` message (a live change: ``profile``)
    dropped: str | None = None  #: why the service did not decode it, where it said so


def event_stacks(reader, *, max_pending: int = MAX_PENDING) -> Iterator[RecordedEventStack]:
    """The stacks of an event recording, as `RecordingReader.stacks` hands on a frame recording's: a
    stack is complete once its output arrived and a later stack started, or once the service
    marked it dropped, or once a stack ``max_pending`` ids later was seen, or at the end of the
    file (``reader.problem`` then says whether the file was cut short).  The topics' last parts
    seen go to ``reader.leaves_seen``."""
    from edge.io.mcap_reader import OutputPairs

    pending: dict[int, dict] = {}
    outputs = OutputPairs()
    newest: int | None = None
    reader.leaves_seen.clear()

    def entry(sid: int) -> dict:
        return pending.setdefault(sid, {"slices": [], "output": None, "info": None, "dropped": None})

    def ready(sid: int) -> bool:
        e = pending[sid]
        return stack_complete(sid, e["output"] is not None, e["dropped"] is not None, newest, max_pending)

    def hand_on(sid: int) -> RecordedEventStack:
        e = pending.pop(sid)
        return RecordedEventStack(sid, e["slices"], e["output"], e["info"], e["dropped"])

    for m in reader.messages():
        leaf = m.topic.rsplit("/", 1)[-1]
        reader.leaves_seen.add(leaf)
        sid = None
        if leaf == TOPIC_LEAF:
            s = parse_event_slice(m.value)
            sid = s.stack
            entry(sid)["slices"].append(s)
            newest = sid if newest is None else max(newest, sid)
        elif leaf == "stack" and isinstance(m.value, dict):
            sid = int(m.value.get("stack", -1))
            if "dropped" in m.value:
                entry(sid)["dropped"] = str(m.value["dropped"])
            else:
                entry(sid)["info"] = m.value
        else:
            out = outputs.take(leaf, m)
            if out is not None:
                sid = out.stack
                entry(sid)["output"] = out
                newest = sid if newest is None else max(newest, sid)
        if sid is None:
            continue
        for k in sorted(pending):
            if ready(k):
                yield hand_on(k)
    for k in sorted(pending):
        yield hand_on(k)


def event_slices(reader) -> Iterator[EventSlice]:
    """The event slices of a recording in file (capture) order."""
    for m in reader.messages():
        if m.topic.rsplit("/", 1)[-1] == TOPIC_LEAF:
            yield parse_event_slice(m.value)

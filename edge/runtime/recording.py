"""Recording off the capture path: a writer thread around `EdgeRecorder` (an
`edge.io.mcap_writer.Recorder` that also writes event slices, `edge.runtime.event_record`).

The capture and decode threads only append to an in-memory queue (bounded by bytes, default
512 MB); one writer thread serialises, compresses and writes.  If the writer ever falls that far
behind, frames are lost and counted (``frames_lost``) instead of stalling capture.  `close`
drains the queue and finishes the file (summary, indexes, CRCs).
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections import deque
from typing import Any

from edge.io.mcap_writer import Recorder

from ..sensors.base import EventSlice, Frame, parse_projector_frame
from .pipeline import DepthResult


#: JSON schema of ``/<device>/config_change`` messages.
CONFIG_CHANGE_SCHEMA = {
    "type": "object", "title": "edge.ConfigChange",
    "properties": {"time_ns": {"type": "integer"}, "keys": {"type": "array", "items": {"type": "string"}},
                   "update": {"type": "object"}, "profile": {"type": "object"}},
}


class EdgeRecorder(Recorder):
    """`Recorder` plus `write_events`: event slices on ``/<device>/events`` (schema ``edge.EventSlice``,
    protobuf; layout in `edge.runtime.event_record`).  The channel is registered on the first slice
    (through the public `Recorder.register_channel`), so frame recordings are unchanged."""

    _events_channel: int | None = None

    def write_events(self, s: EventSlice) -> None:
        from .event_record import event_slice_message, register_events_channel

        cam = self.profile.camera
        data = event_slice_message(s, cam.width, cam.height)
        if self._events_channel is None:
            self._events_channel = register_events_channel(self)
        self.write_message(self._events_channel, data, log_time_ns=s.timestamp_ns, sequence=s.sequence)

    _config_channel: int | None = None

    def write_config_change(self, change: dict[str, Any]) -> None:
        """One accepted config change on ``/<device>/config_change`` (schema ``edge.ConfigChange``)."""
        if self._config_channel is None:
            self._config_channel = self.register_channel("config_change", "edge.ConfigChange", "json",
                                                         json.dumps(CONFIG_CHANGE_SCHEMA).encode())
        self.write_message(self._config_channel, json.dumps(change, default=str).encode(),
                           log_time_ns=int(change["time_ns"]))

    def write_record(self, record, **extra) -> None:
        """A `Frame` (``write_frame`` with its role) or an `EventSlice` (``write_events``)."""
        if isinstance(record, EventSlice):
            self.write_events(record)
        else:
            self.write_frame(record, role=frame_role(record.projector_frame), **extra)


def frame_role(projector_frame: int) -> str:
    """``pattern`` / ``white`` / ``black``, prefixed ``edc-`` for masked adaptive-round frames."""
    pf = parse_projector_frame(projector_frame)
    role = "white" if pf.is_white else "black" if pf.is_black else "pattern"
    return f"edc-{role}" if pf.edc_round else role


class RecordingThread:
    """Asynchronous recorder.  ``on_frame`` / ``on_result`` never block; ``close`` finishes the file."""

    def __init__(self, path: str | os.PathLike[str], profile, *, sensor_metadata: dict[str, Any] | None = None,
                 max_queued_bytes: int = 512 << 20, raw: bool | None = None, outputs: bool | None = None) -> None:
        self.path = os.fspath(path)
        self.recorder = EdgeRecorder(self.path, profile, sensor_metadata=sensor_metadata)
        self.raw = profile.recording.raw if raw is None else raw
        self.outputs = profile.recording.outputs if outputs is None else outputs
        self.max_queued_bytes = int(max_queued_bytes)
        self._items: deque[tuple[str, Any, int]] = deque()
        self._queued_bytes = 0
        self._cond = threading.Condition()
        self._closing = False
        self.frames_written = 0
        self.frames_lost = 0
        self.outputs_written = 0
        self.outputs_lost = 0
        self.write_errors = 0
        self.last_error = ""
        self._write_s = 0.0
        self._started = time.monotonic()
        self._thread = threading.Thread(target=self._loop, name="edge-recorder", daemon=True)
        self._thread.start()

    def _enqueue(self, kind: str, item: Any, nbytes: int) -> bool:
        with self._cond:
            if self._closing or self._queued_bytes + nbytes > self.max_queued_bytes:
                return False
            self._items.append((kind, item, nbytes))
            self._queued_bytes += nbytes
            self._cond.notify()
            return True

    def on_frame(self, frame: Frame | EventSlice) -> None:
        """Queue a camera frame or an event slice (both count as frames in the stats)."""
        nbytes = frame.nbytes if isinstance(frame, EventSlice) else frame.image.nbytes
        if self.raw and not self._enqueue("frame", frame, nbytes):
            self.frames_lost += 1

    def on_result(self, result: DepthResult) -> None:
        if not self.outputs:
            return
        if not self._enqueue("result", result, result.depth_mm.nbytes + result.confidence.nbytes):
            self.outputs_lost += 1

    def on_config_change(self, change: dict[str, Any]) -> None:
        """Queue an accepted config change for ``/<device>/config_change`` (JSON: time_ns, keys,
        update, profile); never dropped for lack of queue space (it is small)."""
        with self._cond:
            if self._closing:
                return
            self._items.append(("config", change, 0))
            self._cond.notify()

    def _write(self, kind: str, item: Any) -> None:
        if kind == "config":
            self.recorder.write_config_change(item)
            return
        if kind == "frame":
            self.recorder.write_record(item)
            self.frames_written += 1
        else:
            r: DepthResult = item
            pts = None
            settings = self.recorder.profile.points
            if settings.record:
                from .points import result_points

                pts = result_points(r, self.recorder.profile.geometry, settings.stride)
            self.recorder.write_depth(r.depth_mm, r.confidence, timestamp_ns=r.timestamp_ns, stack=r.stack,
                                      sequence=r.sequence, edc_rounds=r.edc_rounds,
                                      valid_fraction=round(r.valid_fraction, 6), points=pts,
                                      geometry=r.geometry)
            self.outputs_written += 1

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._items and not self._closing:
                    self._cond.wait(0.5)
                if not self._items and self._closing:
                    return
                kind, item, nbytes = self._items.popleft()
                self._queued_bytes -= nbytes
            t0 = time.perf_counter()
            try:
                self._write(kind, item)
            except Exception as exc:  # keep the service running; report in status
                self.write_errors += 1
                self.last_error = f"{type(exc).__name__}: {exc}"
            self._write_s += time.perf_counter() - t0

    def stats(self) -> dict[str, Any]:
        size = os.path.getsize(self.path) if os.path.exists(self.path) else 0
        elapsed = max(1e-9, time.monotonic() - self._started)
        return {
            "path": self.path, "frames_written": self.frames_written, "frames_lost": self.frames_lost,
            "outputs_written": self.outputs_written, "outputs_lost": self.outputs_lost,
            "bytes": size, "mb_per_s": round(size / elapsed / 1e6, 3),
            "write_busy": round(self._write_s / elapsed, 3), "write_errors": self.write_errors,
        }

    def close(self) -> None:
        """Write everything queued, then finish the MCAP file.  Idempotent."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join()
        self.recorder.finish()

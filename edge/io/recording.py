"""Recording off the capture path: a writer thread around `EdgeRecorder` (an
`edge.io.mcap_writer.Recorder` that also writes event slices, `edge.io.event_record`).

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

from edge.io.mcap_reader import MAX_PENDING
from edge.io.mcap_writer import Recorder
from edge.io.paths import check_folder, check_not_folder, write_target

from ..sensors.base import EventSlice, Frame, parse_projector_frame
from edge.runtime.result import DepthResult


#: JSON schema of ``/<device>/config_change`` messages.
CONFIG_CHANGE_SCHEMA = {
    "type": "object", "title": "edge.ConfigChange",
    "properties": {"time_ns": {"type": "integer"}, "keys": {"type": "array", "items": {"type": "string"}},
                   "update": {"type": "object"}, "profile": {"type": "object"}},
}


def stack_info(result: DepthResult, profile: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ``/<device>/stack`` message of one decoded stack (JSON): what a replay needs to know about
    the stack besides its frames and its depth -- how many camera frames it had (``frames``; a
    replayed stack with fewer raw frames in the file lost some to the recorder) and how many masked
    EDC frames followed (``extra_frames``), its first frame's ``sequence``, when its last frame
    arrived (``received_ns``), the live decode time (``decode_ms``, EDC ``edc_round_ms`` /
    ``edc_capture_ms``) and the pipeline's per-stack counters (``stats``); ``profile`` (a dict of
    `edge.profiles.profile_to_dict`) where given: on the first stack of a file decoded with
    another profile than the file's stored one or the stack before it (a live change;
    `edge.io.replay` switches to it at this stack)."""
    return {"stack": int(result.stack), "sequence": int(result.sequence), "frames": int(result.stack_frames),
            "extra_frames": len(result.extra_frames), "edc_rounds": int(result.edc_rounds),
            "received_ns": int(result.received_ns), "decode_ms": round(result.decode_s * 1e3, 3),
            "edc_round_ms": list(result.edc_round_ms), "edc_capture_ms": list(result.edc_capture_ms),
            "stats": {k: int(v) for k, v in result.stats.items()},
            **({} if profile is None else {"profile": profile})}

class EdgeRecorder(Recorder):
    """`Recorder` plus `write_events`: event slices on ``/<device>/events`` (schema ``edge.EventSlice``,
    protobuf; layout in `edge.io.event_record`).  The channel is registered on the first slice
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
    #: The profile a replay of this file decodes with at the point written so far (`RecordingThread`).
    decoding_profile: Any = None

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


def rotated_path(path: str, series: str, index: int) -> str:
    """``out.mcap`` -> ``out-20260101T120000Z-0003.mcap``: file ``index`` of the rotated recording
    started at UTC time ``series`` (a restarted service starts a new series, never overwrites)."""
    stem, ext = os.path.splitext(path)
    return f"{stem}-{series}-{index:04d}{ext or '.mcap'}"


def series_files(path: str) -> list[str]:
    """Every rotated file of ``path`` on disk (all series), oldest first."""
    import glob

    stem, ext = os.path.splitext(path)
    pattern = glob.escape(stem) + "-" + "[0-9]" * 8 + "T" + "[0-9]" * 6 + "Z-" + "[0-9]" * 4 + glob.escape(ext or ".mcap")
    return sorted(glob.glob(pattern))


def series_stamp() -> str:
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())


class RecordingThread:
    """Asynchronous recorder.  ``on_frame`` / ``on_result`` never block; ``close`` finishes the file.

    Rotation: with ``max_bytes`` and/or ``max_seconds`` the recording is a series of files
    ``<stem>-<UTC start>-0000.mcap``, ``...-0001.mcap``, ... (`rotated_path`); a new file starts at the first
    stack boundary after the current file reached the size or age, and the previous file stays
    open until the stacks it holds are settled (the depth output of its last stack or of a later
    one is written, or the service marks a decode error there, `on_stack_dropped`), or
    `MAX_PENDING` stacks passed; the next rotation waits for that
    (the current file grows past its limit meanwhile), so every file holds whole stacks with
    their outputs and replays on its own.  ``keep`` (> 0) deletes the oldest rotated files of
    ``path`` (earlier series included, e.g. from before a restart) beyond that many: a bounded disk
    footprint for a long unattended run.

    Write failures (disk full, I/O error): recording stops at the first one, the file is finalised
    with what reached the disk (`edge.io.mcap_writer.Recorder`), ``error`` says why, and
    ``frames_written`` / ``outputs_written`` are recounted from the finalised file (what a reader
    will find); every other frame is counted in ``frames_lost``.  The service keeps running.
    """

    def __init__(self, path: str | os.PathLike[str], profile, *, sensor_metadata: dict[str, Any] | None = None,
                 max_queued_bytes: int = 512 << 20, raw: bool | None = None, outputs: bool | None = None,
                 max_bytes: int | None = None, max_seconds: float | None = None, keep: int = 0) -> None:
        self.path = os.fspath(path)
        self.profile = profile
        self.sensor_metadata = sensor_metadata
        self.max_bytes = int(max_bytes) if max_bytes else None
        self.max_seconds = float(max_seconds) if max_seconds else None
        self.keep = int(keep)
        self.rotate = bool(self.max_bytes or self.max_seconds)
        self.files: list[str] = []
        self.series = series_stamp()
        self._index = 0
        self._old: EdgeRecorder | None = None
        self._old_last_stack = -1
        self._last_stack: int | None = None
        self._per_file: dict[str, list[int]] = {}   # path -> [frames, outputs] written into it
        self.recorder = self._open_next()
        self.raw = profile.recording.raw if raw is None else raw
        self.outputs = profile.recording.outputs if outputs is None else outputs
        self.max_queued_bytes = int(max_queued_bytes)
        self._items: deque[tuple[str, Any, int]] = deque()
        self._queued_bytes = 0
        self._cond = threading.Condition()
        self._closing = False
        self._closed = False
        self.stopped = False          # True after a write failure: nothing more is recorded
        self.error = ""               # the write failure, if any
        self.frames_seen = 0
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

    # -- files ---------------------------------------------------------------------------------
    def _open_next(self) -> EdgeRecorder:
        path = rotated_path(self.path, self.series, self._index) if self.rotate else self.path
        rec = EdgeRecorder(path, self.profile, sensor_metadata=self.sensor_metadata)
        rec.decoding_profile = self.profile  # what a replay of this file starts with
        self._index += 1
        self.files.append(path)
        self._per_file[path] = [0, 0]
        self._opened = time.monotonic()
        return rec

    def _profile_change(self, rec: EdgeRecorder, r: DepthResult) -> dict[str, Any] | None:
        """The profile dict to record with ``r``'s stack where its decoding profile is not the one in
        effect in ``rec`` (the file's stored profile, then the last one recorded in it); later
        files open with it.  None where unchanged or unknown."""
        from edge.profiles import profile_to_dict

        if r.profile is None or r.profile == rec.decoding_profile:
            return None
        rec.decoding_profile = r.profile
        self.profile = r.profile
        return profile_to_dict(r.profile)

    def _finish(self, rec: EdgeRecorder) -> None:
        """Finish one file; after a write failure recount what the finalised file holds."""
        try:
            rec.finish()
        finally:
            report = rec.finalize_report
            if report is not None:
                counts = self._per_file.get(rec.path, [0, 0])
                topics = rec.topics
                frames = report.topics.get(topics["raw"], 0) + report.topics.get(topics.get("events", ""), 0)
                outputs = report.topics.get(topics["depth"], 0)
                self.frames_written += frames - counts[0]
                self.outputs_written += outputs - counts[1]
                counts[:] = [frames, outputs]
        self._prune()

    def _prune(self) -> None:
        """With ``keep`` > 0, delete the oldest rotated files until at most ``keep`` remain."""
        if self.keep <= 0 or not self.rotate:
            return
        active = {r.path for r in (self.recorder, self._old) if r is not None}
        files = series_files(self.path)
        for victim in [p for p in files if p not in active][: max(0, len(files) - self.keep)]:
            try:
                os.remove(victim)
            except OSError:
                continue
            if victim in self.files:
                self.files.remove(victim)

    def _rotation_due(self) -> bool:
        if self.max_bytes and self.recorder.bytes_written >= self.max_bytes:
            return True
        return bool(self.max_seconds and time.monotonic() - self._opened >= self.max_seconds)

    def _target(self, stack: int) -> EdgeRecorder:
        """The file a record of ``stack`` goes to (the previous file for its own late records)."""
        if self._old is not None and stack <= self._old_last_stack:
            return self._old
        return self.recorder

    # -- queue ---------------------------------------------------------------------------------
    def _enqueue(self, kind: str, item: Any, nbytes: int) -> bool:
        with self._cond:
            if self._closing or self.stopped or self._queued_bytes + nbytes > self.max_queued_bytes:
                return False
            self._items.append((kind, item, nbytes))
            self._queued_bytes += nbytes
            self._cond.notify()
            return True

    def on_frame(self, frame: Frame | EventSlice) -> None:
        """Queue a camera frame or an event slice (both count as frames in the stats)."""
        if not self.raw:
            return
        self.frames_seen += 1
        nbytes = frame.nbytes if isinstance(frame, EventSlice) else frame.image.nbytes
        if not self._enqueue("frame", frame, nbytes):
            self.frames_lost += 1

    def on_result(self, result: DepthResult) -> None:
        if not self.outputs:
            return
        nbytes = result.depth_mm.nbytes + result.confidence.nbytes + (0 if result.error is None else result.error.nbytes)
        if not self._enqueue("result", result, nbytes):
            self.outputs_lost += 1

    def on_config_change(self, change: dict[str, Any]) -> None:
        """Queue an accepted config change for ``/<device>/config_change`` (JSON: time_ns, keys,
        update, profile); never dropped for lack of queue space (it is small)."""
        with self._cond:
            if self._closing:
                return
            self._items.append(("config", change, 0))
            self._cond.notify()

    def on_stack_dropped(self, stack: int, reason: str) -> None:
        """Queue the ``/<device>/stack`` message of a complete stack the service will not decode
        (``{"stack", "dropped": reason}``: "stale", "decode error"), so that a replay does not wait
        for its depth map; never dropped for lack of queue space (it is small)."""
        if not self.outputs or self.stopped:
            return
        with self._cond:
            if self._closing:
                return
            self._items.append(("dropped", {"stack": int(stack), "dropped": str(reason)}, 0))
            self._cond.notify()

    def _write(self, kind: str, item: Any) -> None:
        if kind == "config":
            self.recorder.write_config_change(item)
            return
        if kind == "dropped":
            rec = self._target(item["stack"])
            rec.write_stack(item, timestamp_ns=time.time_ns())
            # the decode thread takes stacks in order: a decode error at the last stack settles every
            # stack before it too (a stale drop does not: an earlier stack may still be decoding)
            if rec is self._old and item["dropped"] == "decode error" and item["stack"] >= self._old_last_stack:
                self._old = None
                self._finish(rec)
            return
        stack = int(getattr(item, "stack", 0))
        if kind == "frame":
            if self.rotate and self._last_stack is not None and stack > self._last_stack:
                if self._old is not None and stack >= self._old_last_stack + MAX_PENDING:
                    # its last stack got neither a depth map nor a dropped marker this long (the service
                    # marks each stack it drops; a depth map trails its frames by at most its queue)
                    old, self._old = self._old, None
                    self._finish(old)
                if self._rotation_due() and self._old is None:  # else once the previous file is settled
                    self._old, self._old_last_stack = self.recorder, self._last_stack
                    self.recorder = self._open_next()
            self._last_stack = stack if self._last_stack is None else max(self._last_stack, stack)
            rec = self._target(stack)
            rec.write_record(item)
            self.frames_written += 1
            self._per_file[rec.path][0] += 1
        else:
            r: DepthResult = item
            if self._old is not None and r.stack > self._old_last_stack:
                old, self._old = self._old, None
                self._finish(old)
            rec = self._target(r.stack)
            pts = None
            settings = rec.profile.points
            if settings.record:
                from edge.runtime.points import result_points

                pts = result_points(r, rec.profile.geometry, settings.stride)
            # the stack's info first: `RecordingReader.stacks` hands a stack on once its depth is in
            rec.write_stack(stack_info(r, self._profile_change(rec, r)), timestamp_ns=r.timestamp_ns)
            rec.write_depth(r.depth_mm, r.confidence, timestamp_ns=r.timestamp_ns, stack=r.stack,
                            sequence=r.sequence, edc_rounds=r.edc_rounds,
                            valid_fraction=round(r.valid_fraction, 6), points=pts,
                            geometry=r.geometry, error=r.error)
            self.outputs_written += 1
            self._per_file[rec.path][1] += 1
            if rec is self._old and r.stack >= self._old_last_stack:
                self._old = None
                self._finish(rec)

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._items and not self._closing:
                    self._cond.wait(0.5)
                if not self._items and self._closing:
                    return
                kind, item, nbytes = self._items.popleft()
                self._queued_bytes -= nbytes
            if self.stopped:
                self._count_lost(kind)
                continue
            t0 = time.perf_counter()
            try:
                self._write(kind, item)
            except OSError as exc:  # disk full / I/O error: stop recording, keep the service running
                self._count_lost(kind)
                self._stop_recording(exc)
            except Exception as exc:  # one bad record: count it, keep recording
                self.write_errors += 1
                self.last_error = f"{type(exc).__name__}: {exc}"
                self._count_lost(kind)
            self._write_s += time.perf_counter() - t0

    def _count_lost(self, kind: str) -> None:
        if kind in ("config", "dropped"):
            return  # config changes and dropped-stack markers are metadata, not frames or outputs
        if kind == "frame":
            self.frames_lost += 1
        else:
            self.outputs_lost += 1

    def _stop_recording(self, exc: OSError) -> None:
        """First write failure: stop, finalise what reached the disk, drop what is queued."""
        self.write_errors += 1
        failing = next((r for r in (self.recorder, self._old) if r is not None and r.error), self.recorder)
        self.error = (f"{failing.path}: {failing.error or exc}; recording stopped "
                      f"(the file holds what reached the disk; the service keeps publishing)")
        self.last_error = self.error
        self.stopped = True
        with self._cond:
            dropped = list(self._items)
            self._items.clear()
            self._queued_bytes = 0
        for kind, _, _ in dropped:
            self._count_lost(kind)
        for rec in (self._old, self.recorder):
            if rec is None:
                continue
            try:
                self._finish(rec)
            except OSError as fin:
                self.error += f"; finalising {rec.path} failed too ({fin}): salvage it with edge replay --recover"
        self._old = None
        # from now on every frame seen is either in a finalised file or lost
        self.frames_lost = self.frames_seen - self.frames_written

    def stats(self) -> dict[str, Any]:
        # the writer thread may rotate or prune a file between listing and sizing it (keep=N):
        # a file gone meanwhile counts 0 bytes
        size = sum(_size_or_zero(p) for p in list(self.files))
        elapsed = max(1e-9, time.monotonic() - self._started)
        return {
            "path": self.path, "frames_written": self.frames_written, "frames_lost": self.frames_lost,
            "outputs_written": self.outputs_written, "outputs_lost": self.outputs_lost,
            "bytes": size, "mb_per_s": round(size / elapsed / 1e6, 3),
            "write_busy": round(self._write_s / elapsed, 3), "write_errors": self.write_errors,
            "state": "stopped" if self.stopped else "closed" if self._closed else "recording",
            "error": self.error,
            **({"files": list(self.files)} if self.rotate else {}),
        }

    def close(self) -> None:
        """Write everything queued, then finish the MCAP file(s).  Idempotent."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join()
        if self._closed:
            return
        self._closed = True
        if self.stopped:
            return
        try:
            for rec in (self._old, self.recorder):
                if rec is not None:
                    self._finish(rec)
        except OSError as exc:
            self._stop_recording(exc)
        self._old = None
        if self.recorder.finalize_report is not None and not self.error:  # the failure came at finish
            self.stopped = True
            self.error = f"{self.recorder.path}: {self.recorder.error}; the file holds what reached the disk"
            self.frames_lost = self.frames_seen - self.frames_written


def _size_or_zero(path: str) -> int:
    """Bytes of ``path``, 0 where it does not exist (any more)."""
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


def check_record_path(path: str | os.PathLike[str], *, overwrite: bool = False, rotate: bool = False,
                      inputs: tuple[str | os.PathLike[str] | None, ...] = (), option: str = "--record") -> None:
    """Refuse a recording target before anything is opened (ValueError with one line of reason).

    Refused: a directory, a missing or unwritable folder, a name longer than the file system
    allows, something that is not a regular file (``/dev/full``, a FIFO), one of ``inputs`` (the
    replayed recording, also through a symlink or hard link), and an existing recording unless
    ``overwrite`` (rotated recordings start a new, time-stamped series and never overwrite).
    Nothing on disk is changed here.  ``option``: the command-line option the messages name.
    """
    path = os.fspath(path)
    if not path:
        raise ValueError(f"{option}: expected a file name, got ''")
    check_not_folder(path, option=option, example=os.path.join(path, "run.mcap"))
    target = write_target(path)  # a symbolic link: the file it leads to is the one written
    folder = os.fspath(check_folder(os.path.dirname(os.path.abspath(target)), option=option, path=path))
    try:
        name_max = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    names = [os.path.basename(rotated_path(path, series_stamp(), 0) if rotate else path)]
    if any(len(os.fsencode(n)) > name_max for n in names):
        raise ValueError(f"{option} {path}: file name longer than the {name_max} bytes this file system allows")
    for other in inputs:
        if other and os.path.exists(other) and os.path.exists(path) and os.path.samefile(other, path):
            raise ValueError(f"{option} {path} is an input of this command ({other}); write to another file")
    existing = [] if rotate else ([path] if os.path.lexists(target) else [])
    for p in existing:
        if os.path.exists(p) and not os.path.isfile(p):
            raise ValueError(f"{option} {p}: exists and is not a regular file; expected a file name")
    if existing and not overwrite:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise ValueError(f"{option} {existing[0]}{more} already exists; pass --overwrite to replace it "
                         f"(nothing was changed)")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"{option} {path}: folder {folder} is not writable")
    if existing and not all(os.access(p, os.W_OK) for p in existing):
        raise ValueError(f"{option} {path}: the existing file is not writable")

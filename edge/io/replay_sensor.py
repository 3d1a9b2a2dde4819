"""Replay backend: the camera frames of an MCAP recording, at recorded or maximum speed.

Frames come out in file order with their recorded sequence numbers, timestamps, projector frame
ids and stack ids (so gaps and drops in the recording reach the assembler unchanged); an event
recording (``event-dots``) streams its recorded `EventSlice` records the same way.  Masked EDC
frames (edc_round > 0) are not streamed: `capture_masked` hands them back when the adaptive loop
of the same stack asks for them.  Timestamps are re-based to the host wall clock at `start`
(``timestamp_ns`` = start time + recorded offset) so latency figures stay meaningful.
"""

from __future__ import annotations

import dataclasses
import os
import queue
import threading
import time

import numpy as np

from edge.sensors.base import EndOfStream, Frame, SensorInfo, parse_projector_frame


class ReplaySensor:
    """Frames from ``path``; ``max_speed`` = as fast as the consumer reads; ``loop`` = start again at the end."""

    def __init__(self, path: str | os.PathLike[str], *, profile=None, max_speed: bool = False) -> None:
        from edge.device import DeviceModel
        from .mcap import RecordingReader

        self.path = os.fspath(path)
        self.reader = RecordingReader(self.path, expected_profile=profile, strict=False)
        if self.reader.profile is None:
            raise ValueError(f"{self.path}: the recording holds no edge profile; cannot replay it")
        self.profile = self.reader.profile
        model = DeviceModel.from_profile(self.profile)
        cam = self.profile.camera
        self.info = SensorInfo(name="replay", width=cam.width, height=cam.height, bits=cam.bits,
                               fps=0.0 if max_speed else cam.rate_hz, n_code_frames=model.n_code_frames,
                               source_length=model.source_length,
                               metadata={"backend": "replay", "path": self.path, **self.reader.sensor_metadata},
                               layout=model.layout)
        self.events = model.pipeline == "event-dots"
        self.max_speed = max_speed
        self._frames: queue.Queue = queue.Queue(maxsize=256)
        self._masked: dict[int, list[Frame]] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0_host = 0
        self._t0_rec: int | None = None
        self.problem: str | None = None

    def _records(self):
        """Frames (or, for an event recording, `EventSlice` records) in file order."""
        if self.events:
            from edge.io.event_record import event_slices

            yield from event_slices(self.reader)  # capture order, as the frames below
            return
        for f in self.reader.frames():  # capture order (stacks() hands stacks on as their outputs complete)
            yield Frame(f.image, int(f.sequence), int(f.timestamp_ns), float(f.exposure_us),
                        int(f.projector_frame), int(f.stack))

    def _put(self, frame) -> bool:
        while not self._stop.is_set():
            try:
                self._frames.put(frame, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _load(self) -> None:
        try:
            for frame in self._records():
                if parse_projector_frame(frame.projector_frame).edc_round:
                    with self._lock:
                        self._masked.setdefault(frame.stack, []).append(frame)
                    continue
                if not self._put(frame):
                    return
        except Exception as exc:  # a malformed message: end of the readable part, said in status
            self.problem = f"{self.path}: {type(exc).__name__}: {exc}" if not isinstance(exc, ValueError) else str(exc)
        finally:
            self.problem = self.problem or self.reader.problem
            self._frames.put(None)

    def start(self) -> None:
        self._t0_host = time.time_ns()
        self._thread = threading.Thread(target=self._load, name="edge-replay-read", daemon=True)
        self._thread.start()

    def read(self, timeout_s: float = 1.0) -> Frame | None:
        try:
            frame = self._frames.get(timeout=timeout_s)
        except queue.Empty:
            return None
        if frame is None:
            self._frames.put(None)
            raise EndOfStream()
        if self._t0_rec is None:
            self._t0_rec = frame.timestamp_ns
        offset = frame.timestamp_ns - self._t0_rec
        if not self.max_speed:
            wait = (self._t0_host + offset - time.time_ns()) / 1e9
            if wait > 0:
                time.sleep(wait)
        return dataclasses.replace(frame, timestamp_ns=self._t0_host + offset)

    def capture_masked(self, stack: int, edc_round: int, projector_rows: np.ndarray) -> list[Frame]:
        with self._lock:
            frames = [f for f in self._masked.get(stack, [])
                      if parse_projector_frame(f.projector_frame).edc_round == edc_round]
        if len(frames) != len(projector_rows):
            raise ValueError(f"{self.path}: stack {stack} EDC round {edc_round} needs {len(projector_rows)} "
                             f"masked frames, the recording holds {len(frames)}")
        return frames

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)

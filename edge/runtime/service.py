"""The service loop: sensor -> assembly -> bounded queue -> ONE decode thread -> sinks.

Threads (all joined by `Service.stop` / at the end of `Service.run`):

* capture: ``sensor.read`` -> recorder (raw frames, non-blocking hand-off) -> `StackAssembler`
  -> `LatestQueue` (never blocks; a full queue drops its oldest whole stack, counted stale);
* decode: queue -> the profile's pipeline (`make_pipeline`) ``process`` -> every sink's ``on_result`` and the recorder;
  config updates are applied here, between stacks;
* the calling thread of `run` waits, and hands a status dict to the sinks every
  ``zenoh.status_period_s``.

Sinks are plain objects with ``on_result(result)``, ``on_status(status)`` and ``close()`` (the
zenoh publisher and the console printer are sinks).  The recorder has ``on_frame(frame)``,
``on_result(result)``, ``close()`` and runs its own writer thread.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections import deque
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from ..sensors.base import EndOfStream, Frame, MaskedCapture, Sensor
from .assembly import StackAssembler
from .pipeline import DepthResult, make_pipeline
from .stack_queue import Closed, LatestQueue

#: Profile tables that may change while the service runs (applied between stacks).
LIVE_TABLES = ("decoder", "edc", "geometry")
#: The service stops when this many stacks in a row fail to decode (a persistent fault).
MAX_CONSECUTIVE_DECODE_ERRORS = 10


class ConfigRejected(ValueError):
    """A config update the running service refuses; the message is the reason."""


@dataclasses.dataclass
class ServiceCounters:
    stacks_decoded: int = 0
    stacks_published: int = 0
    decode_errors: int = 0
    sink_errors: int = 0
    config_updates: int = 0
    config_rejected: int = 0
    last_error: str = ""


class Service:
    """One device's depth service.

    profile: an `edge.profiles.Profile`; sensor: a started-on-demand `Sensor`; sinks: result
    sinks; recorder: optional recorder; queue_capacity: stacks waiting for the decoder before
    the oldest is dropped; pipeline_factory: builds the per-stack chain (tests inject slow ones).
    """

    def __init__(self, profile, sensor: Sensor, *, sinks: Iterable[Any] = (), recorder: Any = None,
                 queue_capacity: int = 1,
                 pipeline_factory: Callable[[Any], Any] = make_pipeline) -> None:
        self.profile = profile
        self.sensor = sensor
        self.sinks = list(sinks)
        self.recorder = recorder
        self.pipeline_factory = pipeline_factory
        self.pipeline = pipeline_factory(profile)
        self.warm_up_s = 0.0
        schedule = self.pipeline.schedule
        if not np.array_equal(np.asarray(schedule), sensor.info.schedule):
            raise ValueError(
                f"sensor {sensor.info.name!r} sends stacks of {sensor.info.frames_per_stack} frames, "
                f"profile {profile.name!r} expects {len(schedule)}")
        self.assembler = StackAssembler(schedule)
        self.queue: LatestQueue = LatestQueue(queue_capacity)
        self.counters = ServiceCounters()
        self._stop = threading.Event()
        self._capture_done = threading.Event()
        self._threads: list[threading.Thread] = []
        self._pending_profile = None
        self._lock = threading.Lock()
        self._latency_s: deque[float] = deque(maxlen=256)
        self._decode_s: deque[float] = deque(maxlen=256)
        self._result_times: deque[float] = deque(maxlen=64)
        self._target_stacks: int | None = None
        self._started = 0.0
        self.last_result: DepthResult | None = None
        self.results_seen = 0
        self.pipeline_stats: dict[str, int] = {}  # sums of every decoded stack's DepthResult.stats
        #: callables returning extra status fields (e.g. the room claim: room, code, members)
        self.extra_status: list[Callable[[], dict[str, Any]]] = []

    # -- control ------------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask every thread to finish (safe from signal handlers and any thread)."""
        self._stop.set()

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()

    def update_config(self, update: Mapping[str, Any]):
        """Validate a partial profile update and schedule it for the next stack.

        Only the tables in `LIVE_TABLES` may change; anything else, or an invalid value, raises
        `ConfigRejected` / `edge.profiles.ProfileError` (both ValueError) and the running
        configuration is kept.  Returns the new profile.
        """
        from edge.profiles import apply_update, changed_keys

        try:
            new = apply_update(self.profile, update, source="config update")
            frozen = [k for k in changed_keys(self.profile, new) if k.split(".")[0] not in LIVE_TABLES]
            if frozen:
                raise ConfigRejected(
                    f"cannot change {', '.join(frozen)} while running (live tables: {', '.join(LIVE_TABLES)})")
            pipeline = self.pipeline_factory(new)
        except ValueError:
            with self._lock:
                self.counters.config_rejected += 1
            raise
        with self._lock:
            self._pending_profile = (new, pipeline)
            self.profile = new
            self.counters.config_updates += 1
        return new

    def switch_profile(self, new, pipeline=None) -> None:
        """Apply a profile chosen by the service itself (a changed room claim: another source code or
        the other members' codes) between stacks, with ``pipeline`` (default: built from ``new``); the
        stack schedule must stay the same.  Not for user updates (those go through `update_config`)."""
        pipeline = pipeline if pipeline is not None else self.pipeline_factory(new)
        if not np.array_equal(np.asarray(pipeline.schedule), np.asarray(self.pipeline.schedule)):
            raise ValueError(f"profile switch would change the stack schedule of {self.profile.name!r}")
        with self._lock:
            self._pending_profile = (new, pipeline)
            self.profile = new

    # -- threads ------------------------------------------------------------------------------
    def _capture_loop(self) -> None:
        try:
            while not self._stop.is_set():
                try:
                    frame = self.sensor.read(0.1)
                except EndOfStream:
                    break
                if frame is None:
                    continue
                if self.recorder is not None:
                    self.recorder.on_frame(frame)
                stack = self.assembler.push(frame)
                if stack is not None:
                    try:
                        self.queue.put(stack)
                    except Closed:
                        break
        except Exception as exc:  # a broken sensor ends the run with the reason in status
            self.counters.last_error = f"sensor: {type(exc).__name__}: {exc}"
            self._stop.set()
        finally:
            self.assembler.flush(stopping=self._stop.is_set())
            self._capture_done.set()
            self.queue.close()

    def _masked_capture(self) -> Callable[[int, int, np.ndarray], list[Frame]] | None:
        if isinstance(self.sensor, MaskedCapture):
            return self.sensor.capture_masked
        return None

    def _decode_loop(self) -> None:
        masked = self._masked_capture()
        failures = 0
        while True:
            try:
                stack = self.queue.get(0.1)
            except Closed:
                break
            if stack is None:
                continue
            with self._lock:
                pending, self._pending_profile = self._pending_profile, None
            if pending is not None:
                self.pipeline = pending[1]
            try:
                result = self.pipeline.process(stack, masked)
            except Exception as exc:
                self.counters.decode_errors += 1
                self.counters.last_error = f"decode: {type(exc).__name__}: {exc}"
                failures += 1
                if failures >= MAX_CONSECUTIVE_DECODE_ERRORS:  # a persistent fault: stop, do not spin
                    self.counters.last_error += f" ({failures} stacks in a row failed; service stopped)"
                    self._stop.set()
                continue
            failures = 0
            self.counters.stacks_decoded += 1
            self._deliver(result)
            if self._target_stacks is not None and self.counters.stacks_decoded >= self._target_stacks:
                self._stop.set()
                break

    def _deliver(self, result: DepthResult) -> None:
        if self.recorder is not None:
            for frame in result.extra_frames:
                self.recorder.on_frame(frame)
            self.recorder.on_result(result)
        for sink in self.sinks:
            try:
                sink.on_result(result)
            except Exception as exc:
                self.counters.sink_errors += 1
                self.counters.last_error = f"sink: {type(exc).__name__}: {exc}"
        for key, value in result.stats.items():
            self.pipeline_stats[key] = self.pipeline_stats.get(key, 0) + int(value)
        now = time.time_ns()
        self.counters.stacks_published += 1
        self._latency_s.append((now - result.received_ns) / 1e9)
        self._decode_s.append(result.decode_s)
        self._result_times.append(time.monotonic())
        self.last_result = result
        self.results_seen += 1

    # -- status -------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """JSON-able status: rates, latency, drops, decoder, errors."""
        a = self.assembler.counters
        times = list(self._result_times)
        fps = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 and times[-1] > times[0] else 0.0
        lat = np.array(self._latency_s, dtype=np.float64)
        dec = np.array(self._decode_s, dtype=np.float64)
        last = self.last_result
        return {
            "device": self.profile.zenoh.device,
            "profile": self.profile.name,
            "sensor": self.sensor.info.name,
            "uptime_s": round(time.monotonic() - self._started, 3) if self._started else 0.0,
            "warm_up_s": round(self.warm_up_s, 3),
            "fps": round(fps, 3),
            "latency_ms_p50": round(float(np.median(lat)) * 1e3, 3) if lat.size else None,
            "latency_ms_p99": round(float(np.percentile(lat, 99)) * 1e3, 3) if lat.size else None,
            "decode_ms_p50": round(float(np.median(dec)) * 1e3, 3) if dec.size else None,
            "frames_in": a.frames_in,
            "stacks_complete": a.stacks_complete,
            "stacks_decoded": self.counters.stacks_decoded,
            "stacks_dropped": a.stacks_incomplete + self.queue.dropped,
            "stacks_dropped_stale": self.queue.dropped,
            "stacks_dropped_incomplete": a.stacks_incomplete,
            "stacks_cut_at_stop": a.stacks_cut_at_stop,
            "sequence_gaps": a.sequence_gaps,
            "out_of_order": a.out_of_order,
            "edc_rounds": last.edc_rounds if last is not None else 0,
            "decoder": self.profile.decoder.method,
            "code": self.profile.code.name,
            "valid_fraction": round(last.valid_fraction, 4) if last is not None else None,
            "decode_errors": self.counters.decode_errors,
            "sink_errors": self.counters.sink_errors,
            "config_updates": self.counters.config_updates,
            "config_rejected": self.counters.config_rejected,
            "recorder": self.recorder.stats() if self.recorder is not None and hasattr(self.recorder, "stats") else None,
            "sensor_stats": self.sensor.stats() if callable(getattr(self.sensor, "stats", None)) else None,
            "errors": self.counters.last_error,
            **{k: v for k, v in self.pipeline_stats.items() if k not in ("stacks_decoded",)},
            **{k: v for f in self.extra_status for k, v in f().items()},
        }

    def _emit_status(self) -> None:
        status = self.status()
        for sink in self.sinks:
            on_status = getattr(sink, "on_status", None)
            if on_status is None:
                continue
            try:
                on_status(status)
            except Exception as exc:
                self.counters.sink_errors += 1
                self.counters.last_error = f"status: {type(exc).__name__}: {exc}"

    # -- run ----------------------------------------------------------------------------------
    def run(self, *, stacks: int | None = None, seconds: float | None = None,
            on_tick: Callable[["Service"], None] | None = None) -> dict[str, Any]:
        """Run until ``stacks`` depth maps are decoded, ``seconds`` pass, the sensor ends, or
        `stop` is called; then stop cleanly (threads joined, sinks and recorder closed).
        Returns the final status."""
        if stacks is not None and stacks < 1:
            raise ValueError(f"--stacks must be >= 1, got {stacks}")
        if seconds is not None and not seconds > 0:
            raise ValueError(f"--seconds must be > 0, got {seconds}")
        self._target_stacks = stacks
        self._started = time.monotonic()
        deadline = None if seconds is None else self._started + seconds
        period = float(self.profile.zenoh.status_period_s)
        warm_up = getattr(self.pipeline, "warm_up", None)
        if warm_up is not None:  # compile the decoder before frames arrive: no stale stacks at start
            self.warm_up_s = warm_up()
        self.sensor.start()
        try:
            self._threads = [
                threading.Thread(target=self._capture_loop, name="edge-capture", daemon=True),
                threading.Thread(target=self._decode_loop, name="edge-decode", daemon=True),
            ]
            for t in self._threads:
                t.start()
            next_status = time.monotonic() + period
            decode_thread = self._threads[1]
            while decode_thread.is_alive():
                now = time.monotonic()
                if deadline is not None and now >= deadline:
                    self._stop.set()
                if self._stop.is_set():
                    break
                if now >= next_status:
                    self._emit_status()
                    next_status = now + period
                if on_tick is not None:
                    on_tick(self)
                self._stop.wait(min(0.05, max(0.0, next_status - now)))
        finally:
            self._shutdown()
        return self.status()

    def _shutdown(self) -> None:
        self._stop.set()
        capture, decode = self._threads if self._threads else (None, None)
        if capture is not None:
            capture.join(timeout=10)
        try:
            self.sensor.stop()
        except Exception as exc:
            self.counters.last_error = f"sensor stop: {type(exc).__name__}: {exc}"
        self.queue.close()
        if decode is not None:
            decode.join(timeout=60)
        self._emit_status()
        for sink in self.sinks:
            try:
                sink.close()
            except Exception as exc:
                self.counters.last_error = f"sink close: {type(exc).__name__}: {exc}"
        if self.recorder is not None:
            self.recorder.close()

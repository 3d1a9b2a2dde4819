"""The service loop: sensor -> assembly -> bounded queue -> ONE decode thread -> sinks.

Threads (all joined by `Service.stop` / at the end of `Service.run`):

* capture: ``sensor.read`` -> recorder (raw frames, non-blocking hand-off) -> `StackAssembler`
  (which hands each accepted frame to the pipeline's ``on_frame`` hook where it has one: the
  CUDA backend uploads frames as they arrive) -> `LatestQueue` (never blocks; a full queue
  drops its oldest whole stack, counted stale);
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
import sys
import threading
import time
from collections import deque
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from edge.profiles.live import LIVE_TABLES, ConfigRejected  # noqa: F401  (the config-freeze policy; re-exported)

from ..decode.posterior import MIN_FIT_PIXELS
from ..sensors.base import EndOfStream, Frame, MaskedCapture, Sensor
from .assembly import StackAssembler, check_frame_size
from .pipelines import make_pipeline
from .result import DepthResult
from .sdnotify import Notifier
from .stack_queue import Closed, LatestQueue

#: The service stops when this many stacks in a row fail to decode (a persistent fault).
MAX_CONSECUTIVE_DECODE_ERRORS = 10
#: Stacks decoded after a live config change before its cost is checked against the stack budget.
BUDGET_CHECK_STACKS = 3


@dataclasses.dataclass
class ServiceCounters:
    stacks_decoded: int = 0
    stacks_published: int = 0
    decode_errors: int = 0
    sink_errors: int = 0
    config_updates: int = 0
    config_rejected: int = 0
    stacks_dropped_at_stop: int = 0
    noise_fit_fallbacks: int = 0  # stacks whose noise model is the profile's sigmas, not a fit
    last_error: str = ""


class Service:
    """One device's depth service.

    profile: an `edge.profiles.Profile`; sensor: a started-on-demand `Sensor`; sinks: result
    sinks; recorder: optional recorder; queue_capacity: stacks waiting for the decoder before
    the oldest is dropped; pipeline_factory: builds the per-stack chain (tests inject slow ones).
    notifier: systemd notifications (`edge.runtime.sdnotify.Notifier`, default from the
    environment; a no-op outside systemd).  warm_variants: also compile every switchable decoder
    variant before capture (`edge.runtime.warmup`; default: only with the standard pipeline
    factory).  log: one-line warnings (default: stderr).
    """

    def __init__(self, profile, sensor: Sensor, *, sinks: Iterable[Any] = (), recorder: Any = None,
                 queue_capacity: int = 1,
                 pipeline_factory: Callable[[Any], Any] = make_pipeline,
                 notifier: Notifier | None = None, warm_variants: bool | None = None,
                 log: Callable[[str], None] | None = None) -> None:
        from .warmup import WarmUpReport

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
        if (sensor.info.width, sensor.info.height) != (profile.camera.width, profile.camera.height):
            raise ValueError(
                f"sensor {sensor.info.name!r} sends {sensor.info.width}x{sensor.info.height} frames, profile "
                f"{profile.name!r} expects its camera's {profile.camera.width}x{profile.camera.height} (depth and "
                f"intrinsics are the profile's)")
        self.assembler = StackAssembler(schedule, on_frame=getattr(self.pipeline, "on_frame", None))
        self.queue: LatestQueue = LatestQueue(queue_capacity)
        self.counters = ServiceCounters()
        self._stop = threading.Event()
        self._capture_done = threading.Event()
        self._threads: list[threading.Thread] = []
        self._pending_profile = None
        self._lock = threading.Lock()
        self._config_lock = threading.RLock()  # one profile change at a time (live updates, room claims)
        self._latency_s: deque[float] = deque(maxlen=256)
        self._decode_s: deque[float] = deque(maxlen=256)
        self._result_times: deque[float] = deque(maxlen=64)
        self._target_stacks: int | None = None
        self._started = 0.0
        self.last_result: DepthResult | None = None
        self.results_seen = 0
        self.pipeline_stats: dict[str, int] = {}  # sums of every decoded stack's DepthResult.stats
        self.last_noise: tuple[float, float, bool] | None = None  # the last stack's DepthResult.noise
        self.without_contrast = False  # whether the last stack was one no pixel saw the projector in
        self.geometry_source = "profile"  # or "device calibration" (see _use_device_geometry)
        self._last_exposure_us: float | None = None
        self.last_config_change: dict[str, Any] | None = None  # {"time_ns", "keys"} of the last accepted update
        self.notifier = notifier if notifier is not None else Notifier()
        self.warm_variants = (pipeline_factory is make_pipeline) if warm_variants is None else bool(warm_variants)
        self.warm_up_report = WarmUpReport()
        self._variant_labels: set[str] = set()
        if self.warm_variants:
            from .warmup import switchable_variants

            variants = switchable_variants(profile)
            self._variant_labels = {label for label, _ in variants}
            if variants:  # the starting method is warm too: a change can always be switched back
                self._variant_labels.add(f"decoder.method={profile.decoder.method}")
        self.log = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
        self.fault = ""              # why the service stopped itself (sensor failure, persistent decode errors)
        self.warnings: list[str] = []
        self.budget: dict[str, Any] = {}
        self._change: dict[str, Any] | None = None   # the live change being measured against the budget
        self._closed = False
        self._ran = False
        self._sensor_started = False
        #: called by `run` after the sensor started, when ``recorder`` is None (``edge run --record``)
        self.recorder_factory: Callable[[], Any] | None = None
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

        Only the tables in `LIVE_TABLES` may change (`edge.profiles.live_update`, the one
        config-freeze policy); anything else, or an invalid value, raises `ConfigRejected` /
        `edge.profiles.ProfileError` (both ValueError) and the running configuration is kept.
        Returns the new profile.
        """
        from edge.profiles import live_update, profile_to_dict

        with self._config_lock:  # read, build and publish as one step against a concurrent room change
            try:
                new, changed = live_update(self.profile, update, source="config update")
                self._check_warm(self.profile, new)
                if "oak" in {k.split(".")[0] for k in changed}:
                    apply = getattr(self.sensor, "apply_settings", None)
                    if apply is None:
                        raise ConfigRejected(f"sensor {self.sensor.info.name!r} has no OAK emitters to set")
                    apply(new.oak)  # ValueError -> rejected, the running settings are kept
                pipeline = self.pipeline_factory(new)
            except ValueError:
                with self._lock:
                    self.counters.config_rejected += 1
                raise
            change = {"time_ns": time.time_ns(), "keys": changed}
            with self._lock:
                self._pending_profile = (new, pipeline, changed)
                self.profile = new
                self.counters.config_updates += 1
                self.last_config_change = change
        on_change = getattr(self.recorder, "on_config_change", None)
        if on_change is not None:  # the recording says when the decoding settings changed, and to what
            try:
                on_change({**change, "update": dict(update), "profile": profile_to_dict(new)})
            except Exception as exc:  # the change stands; the recording problem goes to status
                self.counters.last_error = f"recorder: {type(exc).__name__}: {exc}"
        return new

    def count_config_rejection(self, reason: str = "") -> None:
        """Count a config update rejected before it reached `update_config` (the zenoh layer)."""
        with self._lock:
            self.counters.config_rejected += 1

    def _check_warm(self, old, new) -> None:
        """ConfigRejected when ``new`` needs kernels that are not compiled (see `edge.runtime.warmup`)."""
        if not self.warm_variants:
            return
        from .warmup import variant_label

        reason = self.warm_up_report.refusal(variant_label(old, new), self._variant_labels)
        if reason:
            raise ConfigRejected(reason)

    # -- warm-up ------------------------------------------------------------------------------
    def warm_up(self) -> bool:
        """Compile the decoder (and its switchable variants) in a helper thread; return True when
        done, False when `stop` was called first (the helper is abandoned: it is a daemon thread
        and capture never starts).  Idempotent; `run` calls it if nobody did."""
        from .warmup import warm_up_all

        if self.warm_up_report.done:
            return True
        if self._stop.is_set():
            return False
        errors: list[BaseException] = []

        def work() -> None:
            try:
                warm_up_all(self.profile, self.pipeline_factory, self.pipeline, variants=self.warm_variants,
                            report=self.warm_up_report, should_stop=self._stop.is_set)
            except BaseException as exc:  # reported by the waiting thread
                errors.append(exc)

        t0 = time.monotonic()
        thread = threading.Thread(target=work, name="edge-warmup", daemon=True)
        thread.start()
        while thread.is_alive() and not self._stop.is_set():
            self.notifier.watchdog()  # alive while compiling (systemd's watchdog may already run)
            thread.join(0.05)
        self.warm_up_s = time.monotonic() - t0
        if errors:
            raise errors[0]
        return self.warm_up_report.done and not self._stop.is_set()

    def switch_profile(self, new) -> None:
        """Apply a profile chosen by the service itself (a changed room claim: another source code or
        the other members' codes) between stacks.  ``new``: the profile, or a function of the running
        profile that returns it (read, built and published under the same lock as `update_config`,
        so that neither undoes a concurrent other).  The pipeline is built with `pipeline_factory`;
        the stack schedule must stay the same.  Not for user updates (those go through
        `update_config`)."""
        with self._config_lock:
            new = new(self.profile) if callable(new) else new
            pipeline = self.pipeline_factory(new)
            if not np.array_equal(np.asarray(pipeline.schedule), np.asarray(self.pipeline.schedule)):
                raise ValueError(f"profile switch would change the stack schedule of {self.profile.name!r}")
            with self._lock:
                self._pending_profile = (new, pipeline, ["room"])  # budget-checked like a live change
                self.profile = new

    # -- threads ------------------------------------------------------------------------------
    def _capture_loop(self) -> None:
        try:
            while not self._stop.is_set():
                try:
                    frame = self.sensor.read(0.1)
                except EndOfStream:
                    problem = getattr(self.sensor, "problem", None)  # e.g. a corrupt replayed recording
                    if problem:
                        self.counters.last_error = f"sensor: {problem}"
                    break
                if frame is None:
                    continue
                self._last_exposure_us = frame.exposure_us
                if self.recorder is not None:
                    self.recorder.on_frame(frame)
                stack = self.assembler.push(frame)
                if stack is not None:
                    try:
                        stale = self.queue.put(stack)
                    except Closed:
                        break
                    if stale is not None:  # the recording says no depth map will come for it
                        self._note_dropped(stale, "stale")
        except Exception as exc:  # a broken sensor ends the run with the reason in status
            self.counters.last_error = f"sensor: {type(exc).__name__}: {exc}"
            self.fault = self.counters.last_error
            self._stop.set()
        finally:
            self.assembler.flush(stopping=self._stop.is_set())
            self._capture_done.set()
            self.queue.close()

    def _use_pipeline(self, pipeline) -> None:
        """Decode with `pipeline` from the next stack on; its capture hook (``on_frame``, e.g. the
        CUDA backend's per-frame uploads; None for the CPU backend) gets the frames assembled from
        now on.  A pipeline with ``continue_from(previous)`` takes over the previous one's staged
        frames (`DepthPipeline.continue_from`); otherwise stacks staged by the previous pipeline's
        hook decode by whole-stack upload."""
        carry = getattr(pipeline, "continue_from", None)
        if carry is not None and pipeline is not self.pipeline:
            carry(self.pipeline)
        self.pipeline = pipeline
        self.assembler.on_frame = getattr(pipeline, "on_frame", None)

    def _masked_capture(self) -> Callable[[int, int, np.ndarray], list[Frame]] | None:
        if isinstance(self.sensor, MaskedCapture):
            return self.sensor.capture_masked
        return None

    def _decode_loop(self) -> None:
        masked = self._masked_capture()
        failures = 0
        while True:
            self.notifier.watchdog()
            if self._stop.is_set():  # stopping: do not decode what is still queued (raw frames are recorded)
                self.counters.stacks_dropped_at_stop += self.queue.discard()
                break
            try:
                stack = self.queue.get(0.1)
            except Closed:
                break
            if stack is None:
                continue
            with self._lock:
                pending, self._pending_profile = self._pending_profile, None
            if pending is not None:
                self._use_pipeline(pending[1])
                self._change = {"keys": list(pending[2]), "decode_s": []}
            try:
                check_frame_size(stack.frames, self.profile.camera)
                result = self.pipeline.process(stack, masked)
            except Exception as exc:
                self.counters.decode_errors += 1
                self.counters.last_error = f"decode: {type(exc).__name__}: {exc}"
                self._note_dropped(stack, "decode error")
                failures += 1
                if failures >= MAX_CONSECUTIVE_DECODE_ERRORS:  # a persistent fault: stop, do not spin
                    self.counters.last_error += f" ({failures} stacks in a row failed; service stopped)"
                    self.fault = self.counters.last_error
                    self._stop.set()
                continue
            failures = 0
            # the profile that decoded it: the recording marks the stack where it changes
            result = dataclasses.replace(result, profile=getattr(self.pipeline, "profile", self.profile))
            self.counters.stacks_decoded += 1
            self._check_budget(result.decode_s)
            self._deliver(result)
            if self._target_stacks is not None and self.counters.stacks_decoded >= self._target_stacks:
                self._stop.set()
                break

    def _note_dropped(self, stack, reason: str) -> None:
        """Tell the recorder that ``stack`` gets no depth map (``reason``: "stale", "decode error"), so
        that a replay knows not to wait for one."""
        note = getattr(self.recorder, "on_stack_dropped", None)
        if note is not None:
            note(int(stack.stack), reason)

    def stack_budget_s(self) -> float:
        """Seconds between two stacks at the camera rate (frames per stack / camera fps)."""
        fps = float(self.profile.camera.rate_hz)
        return self.sensor.info.frames_per_stack / fps if fps > 0 else float("inf")

    def _check_budget(self, decode_s: float) -> None:
        """After a live change, measure `BUDGET_CHECK_STACKS` stacks; a change whose median decode
        time exceeds the stack budget is kept (the operator asked for it) but reported: a warning
        in the status (``budget``, ``warnings``) and on stderr."""
        change = self._change
        if change is None:
            return
        change["decode_s"].append(decode_s)
        if len(change["decode_s"]) < BUDGET_CHECK_STACKS:
            return
        self._change = None
        budget = self.stack_budget_s()
        p50 = float(np.median(change["decode_s"]))
        over = p50 > budget
        self.budget = {"change": ", ".join(change["keys"]) or "(none)", "decode_ms_p50": round(p50 * 1e3, 3),
                       "stack_budget_ms": round(budget * 1e3, 3), "over_budget": over}
        if over:
            warning = (f"config change {self.budget['change']}: decode takes {p50 * 1e3:.0f} ms per stack, over the "
                       f"{budget * 1e3:.0f} ms stack budget ({self.sensor.info.frames_per_stack} frames at "
                       f"{self.profile.camera.rate_hz:g} fps): stacks will be dropped (applied anyway; "
                       f"revert it to keep real time)")
            self.budget["warning"] = warning
            self._warn(warning)

    def _warn(self, warning: str) -> None:
        """A warning for the status (the last 8 are kept) and for stderr."""
        self.warnings.append(warning)
        del self.warnings[:-8]
        self.log(f"edge run: warning: {warning}")

    def _noise_status(self) -> dict[str, Any] | None:
        """The last stack's noise model as sigmas (normalised units: 1 = full scale; variance
        ``sigma_r**2 + sigma_s**2 * I``) and whether it was fitted; None before one (or under the
        "confidence" rule)."""
        if self.last_noise is None:
            return None
        a, beta, fitted = self.last_noise
        return {"sigma_r": round(float(np.sqrt(a)), 6), "sigma_s": round(float(np.sqrt(beta)), 6), "fitted": bool(fitted)}

    def _note_noise(self, result: DepthResult) -> None:
        """Keep the stack's noise model for the status; count the stacks whose model is the
        profile's sigmas (the capture could not be fitted) and warn when that starts."""
        if result.noise is None:
            return
        previous = self.last_noise
        self.last_noise = result.noise
        if result.noise[2]:
            return
        self.counters.noise_fit_fallbacks += 1
        if previous is None or previous[2]:
            a, beta = result.noise[0], result.noise[1]
            warning = (f"decoder: stack {result.stack}: the noise model could not be fitted (fewer than "
                       f"{MIN_FIT_PIXELS} decoded pixels without a sample at 0 or at full scale) and is the "
                       f"profile's sigma_r = {np.sqrt(a):.4g}, sigma_s = {np.sqrt(beta):.4g}; a black level that "
                       f"clips at 0 (no ambient light, no sensor offset) or saturation does this, and the error "
                       f"rule then publishes by the profile's noise, not the camera's")
            self._warn(warning)

    def _note_contrast(self, result: DepthResult) -> None:
        """Warn when stacks in which no pixel sees the projector begin (`NoPatternContrast`: the
        pipeline publishes them as empty depth maps and counts them as ``stacks_without_contrast``);
        one warning per run of such stacks."""
        dark = bool(result.stats.get("stacks_without_contrast"))
        if dark and not self.without_contrast:
            self._warn(f"decoder: stack {result.stack}: no pixel sees the projector (white <= black everywhere): "
                       "it is off or blocked, the lens is covered, or every pixel saturates; empty depth maps "
                       "are published until the pattern is seen again")
        self.without_contrast = dark

    def _deliver(self, result: DepthResult) -> None:
        if result.geometry is None:  # sinks back-project with the geometry that made this depth map
            result = dataclasses.replace(result, geometry=getattr(self.pipeline, "geometry", self.profile.geometry))
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
        self._note_noise(result)
        self._note_contrast(result)
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
            "edc_round_ms": list(getattr(last, "edc_round_ms", ())) if last is not None else [],
            "edc_capture_ms": list(getattr(last, "edc_capture_ms", ())) if last is not None else [],
            "frames_per_depth_map": last.frames_per_depth_map if getattr(last, "stack_frames", 0) else None,
            "decoder": self.profile.decoder.method,
            "code": self.profile.code.name,
            "valid_fraction": round(last.valid_fraction, 4) if last is not None else None,
            "noise_model": self._noise_status(),
            "noise_fit_fallbacks": self.counters.noise_fit_fallbacks,
            "decode_errors": self.counters.decode_errors,
            "sink_errors": self.counters.sink_errors,
            "config_updates": self.counters.config_updates,
            "config_rejected": self.counters.config_rejected,
            "last_config_change": self.last_config_change,
            "stacks_dropped_at_stop": self.counters.stacks_dropped_at_stop,
            "stack_budget_ms": round(self.stack_budget_s() * 1e3, 3),
            "budget": dict(self.budget) or None,
            "warnings": list(self.warnings),
            "warm_up": {"seconds": {k: round(v, 3) for k, v in self.warm_up_report.seconds.items()},
                        "failed": dict(self.warm_up_report.failed), "done": self.warm_up_report.done,
                        "helper": self.warm_up_report.helper},
            "stopping": self._stop.is_set(),
            "fault": self.fault,
            "recorder": self.recorder.stats() if self.recorder is not None and hasattr(self.recorder, "stats") else None,
            "sensor_stats": self.sensor.stats() if callable(getattr(self.sensor, "stats", None)) else None,
            "errors": self.counters.last_error or self._recorder_error(),
            **{k: v for k, v in self.pipeline_stats.items() if k not in ("stacks_decoded",)},
            **self._camera_status(),
            **{k: v for f in self.extra_status for k, v in f().items()},
        }

    def _sensor_device(self) -> dict[str, Any]:
        from edge import __version__

        fn = getattr(self.sensor, "device_status", None)
        if callable(fn):
            try:
                return dict(fn())
            except Exception as exc:
                return {"error": f"{type(exc).__name__}: {exc}"}
        meta = self.sensor.info.metadata or {}
        sim = meta.get("backend") == "sim"
        return {"serial": meta.get("serial") or meta.get("device_id"),
                "firmware": meta.get("firmware") or (f"edge {__version__} simulator" if sim else None),
                "projector_power": self.profile.sim.projector if sim else None, "gain": None}

    def _camera_status(self) -> dict[str, Any]:
        """Exposure, gain, projector power, serial, firmware, edge version and intrinsics (what a
        RealSense / depthai user expects in a status message)."""
        from edge import __version__ as version
        from edge.device import frame_ids

        dev = self._sensor_device()
        g = getattr(self.pipeline, "geometry", None) or self.profile.geometry
        cam = self.profile.camera
        exposure = dev.get("exposure_us") if dev.get("exposure_us") is not None else self._last_exposure_us
        return {
            "edge_version": version,
            "exposure_us": exposure,
            "gain": dev.get("gain", dev.get("iso")),
            "projector_power": dev.get("projector_power", dev.get("dot_intensity")),
            "serial": dev.get("serial"),
            "firmware": dev.get("firmware", dev.get("depthai_version")),
            "intrinsics": {"width": cam.width, "height": cam.height, "fx": g.focal_px, "fy": g.focal_px,
                           "cx": g.cx_camera, "cy": g.cy, "baseline_m": g.baseline_m, "distortion": "none",
                           "frame_id": frame_ids(self.profile.zenoh.device)["optical"],
                           "source": self.geometry_source},
            "sensor_device": dev,
        }

    def _use_device_geometry(self) -> None:
        """After ``sensor.start``: a sensor's own calibration (``device_geometry``, e.g. an OAK's
        ``readCalibration``) replaces the profile's geometry for depth and everything published."""
        geometry = getattr(self.sensor, "device_geometry", None)
        if not geometry:
            return
        from edge.profiles import apply_update

        new = apply_update(self.profile, {"geometry": dict(geometry)}, source=f"{self.profile.source} + device calibration")
        self._use_pipeline(self.pipeline_factory(new))
        self.profile = new
        self.geometry_source = "device calibration"

    def _recorder_error(self) -> str:
        err = getattr(self.recorder, "error", "") if self.recorder is not None else ""
        return f"recording: {err}" if err else ""

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
        self._ran = True
        try:
            # compile the decoder before frames arrive: no stale stacks at start; a stop during
            # warm-up ends the run at once, before the sensor starts
            if self.warm_up():
                self._run_threads(seconds, on_tick)
        finally:
            self._shutdown()
        return self.status()

    def _run_threads(self, seconds: float | None, on_tick: Callable[["Service"], None] | None) -> None:
        self._started = time.monotonic()
        deadline = None if seconds is None else self._started + seconds
        period = float(self.profile.zenoh.status_period_s)
        self._sensor_started = True  # stop() it even if start() fails half-way
        self.sensor.start()
        self._use_device_geometry()  # a sensor's own calibration replaces the profile's geometry
        prepare = getattr(self.pipeline, "prepare_capture", None)
        if prepare is not None:  # e.g. the CUDA backend's pinned buffers, before the first frame
            info = self.sensor.info
            prepare(info.height, info.width, info.bits)
        if self.recorder is None and self.recorder_factory is not None:
            self.recorder = self.recorder_factory()  # the file exists only once capture can start
        self._threads = [
            threading.Thread(target=self._capture_loop, name="edge-capture", daemon=True),
            threading.Thread(target=self._decode_loop, name="edge-decode", daemon=True),
        ]
        for t in self._threads:
            t.start()
        self.notifier.ready(f"capturing: profile {self.profile.name}, sensor {self.sensor.info.name}")
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

    def close(self) -> None:
        """Release everything (sinks, recorder) without running; idempotent.  `run` calls it at
        the end, so call it only for a service that never ran or whose `run` raised early."""
        if not self._closed:
            self._shutdown()

    def _shutdown(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self.notifier.stopping("stopping: finishing the recording")
        capture, decode = self._threads if self._threads else (None, None)
        if capture is not None:
            capture.join(timeout=10)
        try:
            if self._sensor_started:
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
            try:
                self.recorder.close()
            except Exception as exc:  # report, never lose the summary
                self.counters.last_error = f"recording close: {type(exc).__name__}: {exc}"
        self.notifier.close()

"""The simulated sensor (default backend): `edge.sim` driven at the profile's camera rate.

Every stack renders the profile's scene (``profile.sim.scene``, seed ``profile.sim.seed``) at scene
time ``t = stack * frames_per_stack / camera.rate_hz``, so the depth changes over time (the sim
scenes drift in depth / sideways with ``t``).  Projector frames are the code's codebook columns
(projector column x sends codebook row x // stripe), white and black, each spread over the
source-code slots when the profile has one; `edge.sim.capture` forms the images (eq. 1) with the
profile's noise figures and a per-stack seeded RNG, so a stack's images depend only on
(profile, stack id).

Pacing: frame i is released at ``start + i / rate_hz`` (``max_speed=True``: as soon as it is
rendered).  A render thread works one stack ahead.  ``poses=K`` pre-renders K stacks of one
motion period and cycles through them (fresh sequence numbers and timestamps), so that a benchmark
measures the service and not the simulator.  Masked frames for the adaptive EDC loop are rendered
on request for the scene of the stack that asked (`capture_masked`); without global illumination
only the rows with a lit projector pixel are rendered, the dark rows read the stack's black frame.
They are rendered outside the paced stream: a real projector-camera pair spends camera time on
them (the service status reports ``frames_per_depth_map``).

`PacedSensor` holds the machinery (render thread, pacing, poses, scene per stack) shared with the
other simulated backends: `edge.sensors.dots` (dot projector), `edge.sensors.curtain` (light
curtain) and `edge.sensors.event` (event camera).
"""

from __future__ import annotations

import queue
import threading
import time
from collections import OrderedDict

import numpy as np

from edge.triangulation import disparity_from_depth

from .base import BLACK, WHITE, EndOfStream, Frame, SensorInfo, projector_frame_id, stack_schedule

#: seconds of scene time covered by one motion period of the `poses` cycle
MOTION_PERIOD_S = 4.0


def sim_geometry(profile):
    """`edge.sim.Geometry` from a profile's geometry and projector width."""
    from edge.sim.geometry import Geometry

    g = profile.geometry
    return Geometry(focal_px=g.focal_px, baseline_m=g.baseline_m, cx_camera=g.cx_camera,
                    cx_projector=g.cx_projector, cy=g.cy, projector_width=profile.projector.width,
                    projector_height=profile.projector.height)


def sim_camera(profile):
    """`edge.sim.CameraModel` from a profile's camera noise figures and sim light levels."""
    from edge.sim.camera import CameraModel

    c = profile.camera
    return CameraModel(bits=c.bits, sigma_r=c.sigma_r, sigma_s=c.sigma_s, ambient=profile.sim.ambient,
                       projector=profile.sim.projector)


def stack_projector_rows(code, width: int, stripe: int, source: str) -> np.ndarray:
    """(frames_per_stack, width) float32 projector column profiles (0..1) of one stack, schedule
    order: the code frames (`edge.sim.code_profiles`), white, black; every one spread over the
    source-code slots (chip 0 = projector dark) when ``source`` has a 0."""
    from edge.sim import code_profiles

    rows = code_profiles(code, int(width), stripe=int(stripe))
    rows = np.concatenate([rows, np.ones((1, width), np.float32), np.zeros((1, width), np.float32)])
    if source and "0" in source:
        bits = np.array([c == "1" for c in source], dtype=np.float32)
        rows = (rows[:, None, :] * bits[None, :, None]).reshape(-1, width)
    return rows


class PacedSensor:
    """Common machinery of the simulated backends: a render thread one stack ahead, real-time
    pacing at ``camera.rate_hz`` (or ``max_speed``), ``poses`` caching, the scene snapshot per stack.

    Subclasses set ``self.info`` / ``self.schedule`` / ``self.geometry`` before calling
    `_init_stream`, implement ``_render(stack, rng) -> sequence of per-frame payloads`` and may
    override ``_record(payload, position, stack, sequence)`` (default: a `Frame` of the image).
    """

    profile = None
    info: SensorInfo
    schedule: np.ndarray

    def _init_stream(self, profile, *, stacks: int | None, max_speed: bool, poses: int, first_stack: int) -> None:
        if stacks is not None and stacks < 1:
            raise ValueError(f"stacks must be >= 1, got {stacks}")
        if poses < 0:
            raise ValueError(f"poses must be >= 0, got {poses}")
        self.profile = profile
        self.max_stacks = stacks
        self.max_speed = max_speed
        self.poses = int(poses)
        self._next_stack = int(first_stack)
        self._scenes: OrderedDict[int, object] = OrderedDict()
        self._pose_cache: dict[int, object] = {}
        self._rendered: queue.Queue = queue.Queue(maxsize=2)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pending: list = []
        self._pending_stack = -1
        self._sequence = 0
        self._t0 = 0.0
        self._emitted = 0
        self._lock = threading.Lock()

    # -- rendering ----------------------------------------------------------------------------
    def scene_time(self, stack: int) -> float:
        if self.poses:
            return (stack % self.poses) * MOTION_PERIOD_S / self.poses
        return stack * len(self.schedule) / self.profile.camera.rate_hz

    def scene(self, stack: int):
        """The scene snapshot of ``stack`` (kept for the last few stacks, for EDC rounds)."""
        from edge.sim.scenes import make_scene

        with self._lock:
            if stack in self._scenes:
                return self._scenes[stack]
        s = make_scene(self.profile.sim.scene, self.info.width, self.info.height, seed=self.profile.sim.seed,
                       geometry=self.geometry, t=self.scene_time(stack))
        with self._lock:
            self._scenes[stack] = s
            while len(self._scenes) > 4:
                self._scenes.popitem(last=False)
        return s

    def _render(self, stack: int, rng: np.random.Generator):
        raise NotImplementedError

    def render_stack(self, stack: int):
        """The per-frame payloads of ``stack`` (deterministic in profile and stack)."""
        key = stack % self.poses if self.poses else None
        if key is not None and key in self._pose_cache:
            return self._pose_cache[key]
        rng = np.random.default_rng([int(self.profile.sim.seed), int(key if key is not None else stack)])
        out = self._render(stack, rng)
        if key is not None:
            self._pose_cache[key] = out
        return out

    def _record(self, payload, position: int, stack: int, sequence: int):
        return Frame(payload, sequence, time.time_ns(), self.profile.camera.exposure_us,
                     int(self.schedule[position]), stack)

    def _render_loop(self) -> None:
        stack = self._next_stack
        try:
            while not self._stop.is_set():
                if self.max_stacks is not None and stack - self._next_stack >= self.max_stacks:
                    self._rendered.put(None)
                    return
                payloads = self.render_stack(stack)
                while not self._stop.is_set():
                    try:
                        self._rendered.put((stack, payloads), timeout=0.1)
                        break
                    except queue.Full:
                        continue
                stack += 1
        except Exception as exc:  # surfaced by read()
            self._rendered.put(exc)

    # -- Sensor protocol ----------------------------------------------------------------------
    def start(self) -> None:
        self._stop.clear()
        self._t0 = time.monotonic()
        self._emitted = 0
        self._thread = threading.Thread(target=self._render_loop, name="edge-sim-render", daemon=True)
        self._thread.start()

    def read(self, timeout_s: float = 1.0):
        if self._thread is None:
            raise ValueError(f"{type(self).__name__}.read called before start()")
        if not self._pending:
            try:
                item = self._rendered.get(timeout=timeout_s)
            except queue.Empty:
                return None
            if item is None:
                raise EndOfStream()
            if isinstance(item, Exception):
                raise item
            self._pending_stack, payloads = item
            self._pending = list(payloads)
        if not self.max_speed:
            due = self._t0 + self._emitted / self.profile.camera.rate_hz
            wait = due - time.monotonic()
            if wait > timeout_s:
                time.sleep(timeout_s)
                return None
            if wait > 0:
                time.sleep(wait)
            elif wait < -1.0:  # renderer fell far behind: restart the clock instead of bursting
                self._t0 = time.monotonic() - self._emitted / self.profile.camera.rate_hz
        position = len(self.schedule) - len(self._pending)
        payload = self._pending.pop(0)
        frame = self._record(payload, position, self._pending_stack, self._sequence)
        self._sequence += 1
        self._emitted += 1
        return frame

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)


class SimSensor(PacedSensor):
    """Simulated projector-camera sensor for a 'columns' profile (see module docstring).

    stacks: end of stream after this many stacks (None = endless).  max_speed: no pacing.
    poses: pre-render this many stacks and cycle them (0 = render every stack live).
    """

    def __init__(self, profile, *, stacks: int | None = None, max_speed: bool = False, poses: int = 0,
                 first_stack: int = 0, room=None) -> None:
        from edge.codes import get_code

        from .room_model import RoomLight

        self.room = RoomLight(profile, room) if room is not None else None

        if profile.projector.kind != "columns":
            raise ValueError(f"the sim sensor renders 'columns' projectors, profile {profile.name!r} has "
                             f"projector.kind = {profile.projector.kind!r}")
        self.code = get_code(profile.code.name)
        source = profile.code.source if profile.code.source and "0" in profile.code.source else ""
        self.source = source
        L = max(1, len(source))
        cam = profile.camera
        self.info = SensorInfo(
            name="sim", width=cam.width, height=cam.height, bits=cam.bits,
            fps=0.0 if max_speed else cam.rate_hz, n_code_frames=self.code.n, source_length=L,
            metadata={"backend": "sim", "scene": profile.sim.scene, "seed": str(profile.sim.seed)})
        self.schedule = stack_schedule(self.code.n, L)
        self.rows = stack_projector_rows(self.code, profile.projector.width, profile.projector.stripe, source)
        self.geometry = sim_geometry(profile)
        self.camera = sim_camera(profile)
        # fixed total exposure (edge.sim convention): every frame of the stack gets total / n
        self.frame_exposure = self.camera.frame_exposure(self.code.n)
        self._masked_sequence = 0  # masked EDC frames are numbered -1, -2, ... (outside the stream)
        self._blacks: dict[int, np.ndarray] = {}
        self._init_stream(profile, stacks=stacks, max_speed=max_speed, poses=poses, first_stack=first_stack)

    def _capture(self, scene, rows: np.ndarray, rng: np.random.Generator, extra=None) -> np.ndarray:
        from edge.sim import capture

        return capture(scene, rows, self.camera, rng=rng, exposure=self.frame_exposure, extra_irradiance=extra)

    def _render(self, stack: int, rng: np.random.Generator) -> np.ndarray:
        """(frames_per_stack, H, W) camera images of ``stack`` (plus the room's other projectors)."""
        scene = self.scene(stack)
        extra = None
        if self.room is not None:
            own = self.room.own_code()
            if own != self.source:  # the claim changed: project the new code from this stack on
                self.source = own
                self.rows = stack_projector_rows(self.code, self.profile.projector.width,
                                                 self.profile.projector.stripe, own)
            extra = self.foreign_irradiance(stack, scene)
        return self._capture(scene, self.rows, rng, extra)

    def foreign_irradiance(self, stack: int, scene) -> np.ndarray | None:
        """float32 (frames_per_stack, H, W) light of the room's other DLP projectors in my slots.

        Every other member projects its own stack (this profile's code, spread with its family
        code) from its baseline at its room-clock offset (`edge.sensors.room_model`); my slot
        integrates its slots at two sub-samples (fractional offsets)."""
        foreign = self.room.foreign()
        if not foreign:
            return None
        g = self.geometry
        F = len(self.schedule)
        h, w = self.info.height, self.info.width
        wp = int(self.profile.projector.width)
        x = np.arange(w, dtype=np.float64)[None, :]
        t0 = float(stack) * F
        e = np.zeros((F, h, w), np.float32)
        for f in foreign:
            rows_f = stack_projector_rows(self.code, wp, self.profile.projector.stripe, f.code)
            col = x - disparity_from_depth(scene.depth_m.astype(np.float64), g.focal_px * f.baseline_factor,
                                           g.baseline_m, g.doffs)
            ok = np.isfinite(col) & (col >= 0) & (col <= wp - 1)
            ci = np.where(ok, np.rint(np.where(ok, col, 0)), 0).astype(np.int64)
            tau = f.offset_at(t0)
            for i in range(F):
                for sub in (0.25, 0.75):
                    idx = int(np.floor(t0 + i + sub - tau)) % F
                    e[i] += (0.5 * f.power) * np.where(ok, rows_f[idx][ci], 0.0).astype(np.float32)
        return e

    def render_stack(self, stack: int):
        out = super().render_stack(stack)
        with self._lock:  # the stack's black frame, for the dark rows of its masked EDC frames
            self._blacks[stack] = out[-1]
            while len(self._blacks) > 8:
                self._blacks.pop(next(iter(self._blacks)))
        return out

    def _masked_images(self, scene, stack: int, frames_in: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(m, H, W) images of masked projector frames.

        Without global illumination a camera row sees only its own projector row, so rows whose
        projector row is dark in every frame see ambient light only: they read the stack's own
        black frame (same exposure; the same image up to noise) and only the lit rows are rendered.
        """
        from edge.sim.render import has_global_illumination

        if frames_in.ndim != 3 or has_global_illumination(scene) or self.source or self.camera.defocus_sigma > 0:
            return self._capture(scene, frames_in, rng)
        lit_rows = np.nonzero(frames_in.any(axis=0).any(axis=1))[0]
        with self._lock:
            black = self._blacks.get(stack)
        if black is None:
            black = self._capture(scene, np.zeros((1, frames_in.shape[-1]), np.float32), rng)[0]
        images = np.empty((frames_in.shape[0],) + black.shape, dtype=black.dtype)
        images[:] = black
        if lit_rows.size:
            from edge.sim import capture

            images[:, lit_rows] = capture(scene, frames_in, self.camera, rng=rng, exposure=self.frame_exposure,
                                          rows=lit_rows)
        return images

    def capture_masked(self, stack: int, edc_round: int, projector_frames: np.ndarray) -> list[Frame]:
        """Render masked projector frames for the scene of ``stack`` (adaptive EDC loop).

        projector_frames: (m, H, W_projector) or (m, W_projector) projector images (uint8 0..255 or
        float 0..1), as `edge.edc.AdaptiveScan.next_frames` gives them: n masked patterns, a masked
        white [, a black].  Returns m frames with ids (i | WHITE | BLACK, edc_round).
        """
        frames_in = np.asarray(projector_frames)
        if frames_in.ndim not in (2, 3) or frames_in.shape[-1] != self.profile.projector.width:
            raise ValueError(f"masked projector frames must be (m, [H,] {self.profile.projector.width}), "
                             f"got shape {frames_in.shape}")
        m, n = frames_in.shape[0], self.code.n
        if m not in (n, n + 1, n + 2):
            raise ValueError(f"expected {n}..{n + 2} masked frames (patterns [+ white [+ black]]), got {m}")
        rng = np.random.default_rng([int(self.profile.sim.seed), int(stack), 1000 + int(edc_round)])
        scene = self.scene(stack)
        images = self._masked_images(scene, stack, frames_in, rng)
        now = time.time_ns()
        bases = list(range(n)) + [WHITE, BLACK][: m - n]
        out = []
        for img, base in zip(images, bases):
            self._masked_sequence -= 1
            out.append(Frame(img, self._masked_sequence, now, self.profile.camera.exposure_us,
                             projector_frame_id(base, edc_round=edc_round), stack))
        return out

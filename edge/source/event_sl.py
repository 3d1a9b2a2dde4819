"""Event-camera structured light with a source-coded dot projector (paper section 5, example 1).

The device's dot projector switches on/off by its source code (``10100010`` instead of the plain
``10``), one code period per event frame.  The scene comes from `edge.sim`; an interfering device
(a second dot projector at another baseline with its own code, slot length and phase, e.g. a
RealSense-like ``10`` square wave) and optional flickering ambient light add events.  Processing:
events -> matched filter per pixel and period (`edge.source.matched_filter`) -> filtered event frame
(pixels with kept "on" events) -> disparity by block matching against the reference dot pattern ->
depth.  Without coding, the event frame takes every positive event of the period.

Intensity at a camera pixel (linear, noise-free; the DVS adds its own noise):

    I(t) = albedo * (P * s_own(t) * E_own + P_f * s_f(t) * E_f + A * (1 + m sin(2 pi f t)))

with E_own the own projector's dot irradiance (`edge.sim.projector_irradiance`) and E_f the foreign
dots warped through the scene depth from the foreign projector's baseline.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..codes.source import SourceCode, source_code
from ..sim import CameraModel, Geometry, Scene, make_scene, projector_irradiance
from ..triangulation import disparity_from_depth
from .dots import block_match, random_dots
from .events import EventSensor, event_frame, simulate_events
from .matched_filter import DEFAULT_EVENT_THRESHOLD, filter_events

LABEL_OWN, LABEL_FOREIGN, LABEL_AMBIENT = 1, 2, 4


@dataclass(frozen=True)
class Interferer:
    """A foreign dot projector: its own code (``"10"`` = plain on/off), slot length, phase and place."""

    code: str = "10"
    slot_us: float = 1300.0
    phase_us: float = 370.0
    baseline_m: float = 0.05
    power: float = 1.5
    dot_density: float = 0.3
    seed: int = 99


@dataclass(frozen=True)
class EventSLConfig:
    """Scenario parameters (times in microseconds, light levels relative to the white surface)."""

    width: int = 320
    height: int = 240
    scene: str = "steps"
    seed: int = 1
    code: str = "10100010"
    slot_us: int = 1000
    periods: int = 4
    dot_density: float = 0.12
    power: float = 1.0
    ambient: float = 0.1
    flicker_hz: float = 0.0
    flicker_depth: float = 0.3
    substeps: int = 4
    interferer: Interferer | None = field(default_factory=Interferer)
    threshold: float = DEFAULT_EVENT_THRESHOLD
    sensor: dict = field(default_factory=dict)

    def geometry(self) -> Geometry:
        f = 300.0 * self.width / 320.0
        return Geometry.default(self.width, self.height, focal_px=f, cx_projector=self.width / 2.0,
                                projector_width=self.width)


@dataclass(frozen=True)
class EventSLResult:
    """One run.  events (EVENT_DTYPE), labels (uint8 bit mask), keep (bool, the filter's decision or
    all True without coding), frames (periods, H, W) int32 dot images, disparity (periods, H, W)
    float32 (NaN = none), scene, reference (H, W) bool dot pattern, code used, coded flag."""

    events: np.ndarray
    labels: np.ndarray
    keep: np.ndarray
    frames: np.ndarray
    disparity: np.ndarray
    scene: Scene
    reference: np.ndarray
    code: SourceCode
    coded: bool
    band: tuple[int, int]
    period: np.ndarray


def _foreign_irradiance(scene: Scene, dots: np.ndarray, baseline_m: float) -> np.ndarray:
    """Irradiance (H, W) float32 of a dot projector at ``baseline_m`` (same rows, principal point and
    focal length as ours) on the scene's surfaces (no shadows modelled)."""
    g = scene.geometry
    h, w = scene.shape
    col = np.arange(w)[None, :] - disparity_from_depth(scene.depth_m, g.focal_px, baseline_m, g.doffs)
    ok = np.isfinite(col)
    ci = np.where(ok, np.floor(col + 0.5), -1).astype(np.int64)
    ok &= (ci >= 0) & (ci < dots.shape[1])
    rows = np.broadcast_to(np.arange(h)[:, None], (h, w))
    out = np.zeros((h, w), np.float32)
    out[ok] = dots[rows[ok], ci[ok]]
    return out


#: Public name of `_foreign_irradiance` (used by the service's event backend, `edge.sensors.event`).
foreign_irradiance = _foreign_irradiance


def _state(bits: np.ndarray, slot_us: float, phase_us: float, t: np.ndarray) -> np.ndarray:
    idx = np.floor((t - phase_us) / slot_us).astype(np.int64) % bits.size
    return bits[idx].astype(np.float64)


def run_event_sl(cfg: EventSLConfig, *, coded: bool = True, interference: bool = True,
                 rng_seed: int = 0) -> EventSLResult:
    """Simulate one scenario and process it; ``coded=False`` projects ``10`` and keeps every event."""
    code = source_code(cfg.code) if coded else source_code("10")
    geometry = cfg.geometry()
    scene = make_scene(cfg.scene, cfg.width, cfg.height, seed=cfg.seed, geometry=geometry)
    ref = random_dots(cfg.width, cfg.height, density=cfg.dot_density, seed=cfg.seed + 7)
    e_own = projector_irradiance(scene, ref[None].astype(np.float32), CameraModel())[0]
    inter = cfg.interferer if interference else None
    e_f = (_foreign_irradiance(scene, random_dots(cfg.width, cfg.height, density=inter.dot_density, seed=inter.seed),
                               inter.baseline_m) if inter is not None else None)
    period_us = code.length * cfg.slot_us
    end = cfg.periods * period_us
    times = [np.arange(0, end, cfg.slot_us, dtype=np.float64)]
    if cfg.flicker_hz > 0:
        times.append(np.arange(0, end, cfg.slot_us / cfg.substeps, dtype=np.float64))
    if inter is not None:
        fb = inter.phase_us % inter.slot_us + np.arange(0, end / inter.slot_us + 1) * inter.slot_us
        times.append(np.floor(fb[fb < end]))
    t = np.unique(np.concatenate(times)).astype(np.int64)
    labels = np.zeros(t.size, np.uint8)
    s_own = _state(code.bits, cfg.slot_us, 0.0, t.astype(np.float64))
    labels[np.r_[False, np.diff(s_own) != 0]] |= LABEL_OWN
    amb = np.full(t.size, cfg.ambient)
    if cfg.flicker_hz > 0:
        amb = cfg.ambient * (1.0 + cfg.flicker_depth * np.sin(2 * np.pi * cfg.flicker_hz * t * 1e-6))
        labels[np.r_[False, np.diff(amb) != 0]] |= LABEL_AMBIENT
    inten = (scene.albedo[None] * (cfg.power * s_own[:, None, None] * e_own[None] + amb[:, None, None])).astype(np.float32)
    if inter is not None:
        fcode = source_code(inter.code)
        s_f = _state(fcode.bits, inter.slot_us, inter.phase_us, t.astype(np.float64))
        labels[np.r_[False, np.diff(s_f) != 0]] |= LABEL_FOREIGN
        inten += (scene.albedo * inter.power * e_f)[None] * s_f[:, None, None].astype(np.float32)
    sensor = EventSensor(cfg.width, cfg.height, **cfg.sensor)
    rng = np.random.default_rng(rng_seed)
    events, lab = simulate_events(inten, t, sensor, rng=rng, end_us=int(end), step_labels=labels, return_labels=True)
    # labels come per step; keep the own / foreign bit only where that projector actually lights the pixel
    ex, ey = events["x"].astype(np.int64), events["y"].astype(np.int64)
    lab = lab.copy()
    not_own = (lab != 128) & (e_own[ey, ex] <= 0)
    lab[not_own] &= np.uint8(~LABEL_OWN & 0xFF)
    if e_f is not None:
        not_f = (lab != 128) & (e_f[ey, ex] <= 0)
        lab[not_f] &= np.uint8(~LABEL_FOREIGN & 0xFF)
    t0 = sensor.latency_us
    if coded:
        res = filter_events(events, code, width=cfg.width, height=cfg.height, slot_us=cfg.slot_us, t0_us=t0,
                            threshold=cfg.threshold)
        keep = res.keep
    else:
        keep = np.ones(events.size, bool)
    guard = cfg.slot_us // 4
    period = (events["t"].astype(np.int64) - t0 + guard) // period_us
    lo, hi = scene.disparity_band(margin=4)
    frames = np.zeros((cfg.periods, cfg.height, cfg.width), np.int32)
    disp = np.full((cfg.periods, cfg.height, cfg.width), np.nan, np.float32)
    for k in range(cfg.periods):
        sel = keep & (period == k)
        frames[k] = event_frame(events, cfg.width, cfg.height, polarity=1, mask=sel)
        disp[k] = block_match(frames[k], ref, min_disparity=lo, max_disparity=hi)
    return EventSLResult(events, lab, keep, frames, disp, scene, ref, code, coded, (lo, hi), period)


def event_metrics(result: EventSLResult, reference: EventSLResult | None = None, *, skip_first: bool = True) -> dict:
    """Event and disparity metrics of a run.

    own_kept: fraction of own-projector events kept; interference_rejected: fraction of foreign
    events (and ambient-flicker events, background activity) rejected; disparity metrics over
    periods (first skipped: the sensor starts from the initial level) on lit pixels: ``valid``
    fraction, ``mae_px`` and ``bad1`` (|error| > 1 px) against ground truth, and ``agree1`` =
    fraction of the interference-free run's valid pixels that this run matches within 1 px.
    """
    sel = result.period >= (1 if skip_first else 0)  # the sensor starts from the first level: no first edge
    lab, keep = result.labels[sel], result.keep[sel]
    bg = lab == 128
    has_own = ((lab & LABEL_OWN) > 0) & ~bg
    has_foreign = ((lab & LABEL_FOREIGN) > 0) & ~bg
    own = has_own & ~has_foreign
    foreign = has_foreign & ~has_own
    amb = (lab == LABEL_AMBIENT)
    frac = lambda m, k: float(k[m].mean()) if m.any() else float("nan")  # noqa: E731
    out = {
        "events": int(lab.size),
        "own_events": int(own.sum()), "foreign_events": int(foreign.sum()),
        "ambient_events": int(amb.sum()), "background_events": int(bg.sum()),
        "own_kept": frac(own, keep),
        "interference_rejected": frac(foreign, ~keep),
        "ambient_rejected": frac(amb, ~keep),
        "background_rejected": frac(bg, ~keep),
    }
    ks = range(1 if skip_first and result.disparity.shape[0] > 1 else 0, result.disparity.shape[0])
    gt = result.scene.disparity
    lit = result.scene.lit
    valid, mae, bad1, agree = [], [], [], []
    for k in ks:
        d = result.disparity[k]
        ok = lit & np.isfinite(d)
        valid.append(ok.sum() / max(1, lit.sum()))
        err = np.abs(d[ok] - gt[ok])
        mae.append(float(err.mean()) if err.size else np.nan)
        bad1.append(float((err > 1).mean()) if err.size else np.nan)
        if reference is not None:
            r = reference.disparity[min(k, reference.disparity.shape[0] - 1)]
            rv = lit & np.isfinite(r)
            both = rv & np.isfinite(d)
            agree.append(float((np.abs(d[both] - r[both]) <= 1).sum() / max(1, rv.sum())))
    out.update(valid=float(np.mean(valid)), mae_px=float(np.nanmean(mae)), bad1=float(np.nanmean(bad1)))
    if reference is not None:
        out["agree1"] = float(np.mean(agree))
    return out

"""Event-camera structured light with a source-coded dot projector (paper section 5, example 1).

The device's dot projector switches on/off by its source code (``10100010`` instead of the plain
``10``), one code period per event frame.  The scene comes from `edge.sim`; an interfering device
(a second dot projector at another baseline with its own code, slot length and phase, e.g. a
RealSense-like ``10`` square wave) and optional flickering ambient light add events.  Processing:
events -> matched filter per pixel and period (`edge.source.matched_filter`) -> filtered event frame
(pixels with kept "on" events) -> disparity by block matching against the reference dot pattern ->
depth.  Without coding, the event frame takes every positive event of the period.

This module holds the model and the processing as pure functions: `event_intensity` (the light
at every pixel over time, with the step labels), `label_events` (which light made each event) and
`decode_event_frames` (matched filter -> dot frames -> disparity).  The scenario runner and its
metrics are `edge.eval.event_sl`.

Intensity at a camera pixel (linear, noise-free; the DVS adds its own noise):

    I(t) = albedo * (P * s_own(t) * E_own + P_f * s_f(t) * E_f + A * (1 + m sin(2 pi f t)))

with E_own the own projector's dot irradiance (`edge.sim.projector_irradiance`) and E_f the foreign
dots warped through the scene depth from the foreign projector's baseline.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..codes.source import SourceCode, source_code
from ..sim import Geometry, Scene
from ..triangulation import disparity_from_depth
from .dots import block_match
from .events import LABEL_BACKGROUND, event_frame
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

    def __post_init__(self) -> None:
        for name in ("width", "height", "slot_us", "periods", "substeps"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name}: expected >= 1, got {getattr(self, name)}")
        for name in ("flicker_hz", "flicker_depth", "ambient", "power", "dot_density"):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v < 0.0:
                raise ValueError(f"{name}: expected a finite value >= 0, got {getattr(self, name)}")

    def geometry(self) -> Geometry:
        return Geometry.projector_as_wide(self.width, self.height)


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


def event_intensity(scene: Scene, cfg: EventSLConfig, code: SourceCode, e_own: np.ndarray,
                    e_f: np.ndarray | None, inter: Interferer | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The light of the scenario at every change of any source (noise-free, linear).

    e_own, e_f: (H, W) float32 own / foreign dot irradiance (e_f None without interferer ``inter``).
    Returns (t (T,) int64 microseconds, intensity (T, H, W) float32, step labels (T,) uint8 bit
    mask of `LABEL_OWN` / `LABEL_FOREIGN` / `LABEL_AMBIENT`: which source changed at that step).
    """
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
    return t, inten, labels


def label_events(events: np.ndarray, labels: np.ndarray, e_own: np.ndarray, e_f: np.ndarray | None) -> np.ndarray:
    """Per-event labels (uint8; `LABEL_BACKGROUND` = background activity) with the own / foreign bit kept only
    where that projector actually lights the event's pixel (``e_own`` / ``e_f`` > 0)."""
    ex, ey = events["x"].astype(np.int64), events["y"].astype(np.int64)
    lab = labels.copy()
    not_own = (lab != LABEL_BACKGROUND) & (e_own[ey, ex] <= 0)
    lab[not_own] &= np.uint8(~LABEL_OWN & 0xFF)
    if e_f is not None:
        not_f = (lab != LABEL_BACKGROUND) & (e_f[ey, ex] <= 0)
        lab[not_f] &= np.uint8(~LABEL_FOREIGN & 0xFF)
    return lab


def decode_event_frames(events: np.ndarray, code: SourceCode, cfg: EventSLConfig, reference: np.ndarray,
                        band: tuple[int, int], *, coded: bool, t0_us: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Events -> (keep (E,) bool, period (E,) int64, dot frames (periods, H, W) int32, disparity
    (periods, H, W) float32, NaN = none).

    coded: the matched filter (`filter_events`, ``cfg.threshold``) decides which events to keep;
    otherwise every event is kept.  Period k's frame counts the kept "on" events of code period
    k (times from ``t0_us``, a quarter slot of guard) and is block-matched against ``reference``
    over the disparity ``band``.
    """
    if coded:
        res = filter_events(events, code, width=cfg.width, height=cfg.height, slot_us=cfg.slot_us, t0_us=t0_us,
                            threshold=cfg.threshold)
        keep = res.keep
    else:
        keep = np.ones(events.size, bool)
    period_us = code.length * cfg.slot_us
    guard = cfg.slot_us // 4
    period = (events["t"].astype(np.int64) - t0_us + guard) // period_us
    lo, hi = band
    frames = np.zeros((cfg.periods, cfg.height, cfg.width), np.int32)
    disp = np.full((cfg.periods, cfg.height, cfg.width), np.nan, np.float32)
    for k in range(cfg.periods):
        sel = keep & (period == k)
        frames[k] = event_frame(events, cfg.width, cfg.height, polarity=1, mask=sel)
        disp[k] = block_match(frames[k], reference, min_disparity=lo, max_disparity=hi)
    return keep, period, frames, disp

"""Evaluation of event-camera structured light with a source-coded dot projector (paper section 5,
example 1): `run_event_sl` runs one scenario of `edge.source.event_sl.EventSLConfig` end to end,
`event_metrics` scores it, `scenarios` is the grid both reports run (uncoded / coded x clean /
interference; ``edge source event-demo``, ``tools/eval_source.py``).

The model and the processing are `edge.source.event_sl` (`event_intensity`, `label_events`,
`decode_event_frames`); the DVS is `edge.source.events`; this module only wires them to a
simulated scene (`edge.sim`) and compares with the ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..codes.source import SourceCode, source_code
from ..sim import CameraModel, Scene, make_scene, projector_irradiance
from ..source.dots import random_dots
from ..source.event_sl import (LABEL_AMBIENT, LABEL_FOREIGN, LABEL_OWN, EventSLConfig, decode_event_frames,
                               event_intensity, foreign_irradiance, label_events)
from ..source.events import EventSensor, simulate_events


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


def run_event_sl(cfg: EventSLConfig, *, coded: bool = True, interference: bool = True,
                 rng_seed: int = 0) -> EventSLResult:
    """Simulate one scenario and process it; ``coded=False`` projects ``10`` and keeps every event."""
    code = source_code(cfg.code) if coded else source_code("10")
    geometry = cfg.geometry()
    scene = make_scene(cfg.scene, cfg.width, cfg.height, seed=cfg.seed, geometry=geometry)
    ref = random_dots(cfg.width, cfg.height, density=cfg.dot_density, seed=cfg.seed + 7)
    e_own = projector_irradiance(scene, ref[None].astype(np.float32), CameraModel())[0]
    inter = cfg.interferer if interference else None
    e_f = (foreign_irradiance(scene, random_dots(cfg.width, cfg.height, density=inter.dot_density, seed=inter.seed),
                              inter.baseline_m) if inter is not None else None)
    t, inten, labels = event_intensity(scene, cfg, code, e_own, e_f, inter)
    end = cfg.periods * code.length * cfg.slot_us
    sensor = EventSensor(cfg.width, cfg.height, **cfg.sensor)
    rng = np.random.default_rng(rng_seed)
    events, lab = simulate_events(inten, t, sensor, rng=rng, end_us=int(end), step_labels=labels, return_labels=True)
    lab = label_events(events, lab, e_own, e_f)
    band = scene.disparity_band(margin=4)
    keep, period, frames, disp = decode_event_frames(events, code, cfg, ref, band, coded=coded,
                                                     t0_us=sensor.latency_us)
    return EventSLResult(events, lab, keep, frames, disp, scene, ref, code, coded, band, period)


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


def run_label(cfg: EventSLConfig, coded: bool) -> str:
    """How reports name a run: ``"coded <code>"`` or ``"uncoded 10"``."""
    return f"coded {cfg.code}" if coded else "uncoded 10"


def scenarios(cfg: EventSLConfig) -> list[tuple[bool, str, EventSLResult, dict]]:
    """The evaluation grid: (coded, "clean" | "interference", result, `event_metrics`) for uncoded
    then coded projection, each without and with the interferer (the interference run is scored
    against the clean one)."""
    out = []
    for coded in (False, True):
        clean = run_event_sl(cfg, coded=coded, interference=False)
        noisy = run_event_sl(cfg, coded=coded, interference=True)
        for name, res, ref in (("clean", clean, None), ("interference", noisy, clean)):
            out.append((coded, name, res, event_metrics(res, ref)))
    return out

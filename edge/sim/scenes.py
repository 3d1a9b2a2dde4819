"""Scene generators: ``make_scene(name, width, height, *, seed=0, geometry=None, **params)``.

Every scene is deterministic given ``seed`` (and ``t``), stays within 0.4..2.0 m of the default
geometry, and accepts these common parameters:

- ``t`` (seconds, default 0): time of the snapshot.  ``flying`` objects drift sideways and in
  depth; ``sphere`` moves sideways; the other analytic scenes move back and forth in depth by
  ``motion`` metres (default 0.05) with a 4 s period.
- ``interreflection`` (>= 0): one-bounce strength (1 = physical).  Default 1 for ``v-groove`` and
  ``bowl``, 0 otherwise.
- ``scattering`` (0..1): sub-surface scattering strength inside the scene's scattering regions
  (``flying``: every third object; analytic scenes: a central ellipse), footprint
  ``scattering_sigma`` pixels (default 3).  Default 0 except for the ``scattering`` scene (0.8).
- ``texture`` (0..1, default 1): contrast of the albedo texture (0 = uniform albedo ``albedo``).
- ``albedo`` (default 0.7): mean albedo of analytic scenes.
- ``bounces`` (default 1), ``gloss`` (default 0 = diffuse; > 0: Phong exponent of a specular-ish
  lobe), ``gi_patch`` (default 16 pixels): inter-reflection model, see `edge.sim.gi`.

Scene names: flying, plane, tilted-plane, steps, sphere, v-groove, bowl, scattering.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import cv2
import numpy as np

from .geometry import Geometry
from .scene import Scene, build_scene

_COMMON = {"t": 0.0, "interreflection": None, "scattering": None, "scattering_sigma": 3.0, "texture": 1.0,
           "albedo": 0.7, "motion": 0.05, "bounces": 1, "gloss": 0.0, "gi_patch": 16}


def smooth_noise(rng: np.random.Generator, height: int, width: int, *, scales: tuple[int, ...] = (4, 16, 64)) -> np.ndarray:
    """(H, W) float32 noise in [0, 1]: sum of bilinearly upsampled random grids of given cell sizes."""
    total = np.zeros((height, width), np.float32)
    weight = 0.0
    for cell in scales:
        gh, gw = max(2, height // cell + 2), max(2, width // cell + 2)
        grid = rng.random((gh, gw), dtype=np.float32)
        up = cv2.resize(grid, (gw * cell, gh * cell), interpolation=cv2.INTER_LINEAR)[:height, :width]
        total += up * cell
        weight += cell
    total /= weight
    lo, hi = float(total.min()), float(total.max())
    return (total - lo) / max(hi - lo, 1e-6)


def texture(rng: np.random.Generator, height: int, width: int, mean: float, contrast: float) -> np.ndarray:
    """Albedo texture (H, W) float32: smooth noise plus a few sharp-edged blotches around ``mean``."""
    n = smooth_noise(rng, height, width)
    blot = np.zeros((height, width), np.float32)
    for _ in range(max(1, (height * width) // 20000)):
        cx, cy = int(rng.integers(0, width)), int(rng.integers(0, height))
        ax, ay = int(rng.integers(3, max(4, width // 10))), int(rng.integers(3, max(4, height // 10)))
        cv2.ellipse(blot, (cx, cy), (ax, ay), float(rng.uniform(0, 180)), 0, 360, float(rng.uniform(-1, 1)), -1)
    a = mean * (1.0 + contrast * (0.8 * (n - 0.5) + 0.35 * blot))
    return np.clip(a, 0.02, 1.0).astype(np.float32)


def _plane_depth(geometry: Geometry, width: int, height: int, z0: float, sx: float, sy: float) -> np.ndarray:
    """Depth of the plane through (0, 0, z0) with normal (sx, sy, 1): Z = z0 / (1 + sx*u + sy*v)."""
    u, v = geometry.rays(width, height)
    return (z0 / (1.0 + sx * u[None, :] + sy * v[:, None])).astype(np.float64)


def _wave(t: float, period: float = 4.0) -> float:
    return math.sin(2.0 * math.pi * t / period)


def _central_ellipse(width: int, height: int) -> np.ndarray:
    m = np.zeros((height, width), np.uint8)
    cv2.ellipse(m, (width // 2, height // 2), (max(2, width // 5), max(2, height // 4)), 0, 0, 360, 1, -1)
    return m.astype(bool)


# ----------------------------------------------------------------------------------------- flying

def _flying(width: int, height: int, geometry: Geometry, rng: np.random.Generator, p: dict[str, Any]):
    n_objects = int(p.get("objects", 12))
    t = float(p["t"])
    contrast = float(p["texture"])
    scale = min(width, height)
    bg_sx, bg_sy = rng.uniform(-0.35, 0.35), rng.uniform(-0.2, 0.2)
    depth = np.minimum(_plane_depth(geometry, width, height, 1.45, bg_sx, bg_sy), 2.0)
    albedo = texture(rng, height, width, float(rng.uniform(0.4, 0.6)), contrast)
    # a dark and a bright region on the background
    for level in (0.08, 0.95):
        m = np.zeros((height, width), np.uint8)
        cv2.rectangle(m, (int(rng.integers(0, width)), int(rng.integers(0, height))),
                      (int(rng.integers(0, width)), int(rng.integers(0, height))), 1, -1)
        albedo = np.where(m > 0, np.clip(level + 0.05 * (albedo - 0.5), 0.02, 1.0), albedo)
    oid = np.zeros((height, width), np.int32)
    scat = np.zeros((height, width), np.float32)
    u, v = geometry.rays(width, height)
    for k in range(n_objects):
        kind = ["ellipse", "polygon", "rectangle", "bar"][k % 4] if k < 4 else \
            ["ellipse", "polygon", "rectangle", "bar"][int(rng.integers(0, 4))]
        size = int(rng.uniform(0.06, 0.22) * scale) + 2
        half = size if kind != "bar" else int(rng.uniform(0.25, 0.45) * scale)
        tile = np.zeros((2 * half + 1, 2 * half + 1), np.uint8)
        c = (half, half)
        if kind == "ellipse":
            cv2.ellipse(tile, c, (size, max(2, int(size * rng.uniform(0.3, 1.0)))), float(rng.uniform(0, 180)),
                        0, 360, 1, -1)
        elif kind == "polygon":
            angles = np.sort(rng.uniform(0, 2 * np.pi, int(rng.integers(3, 7))))
            radii = rng.uniform(0.4, 1.0, angles.size) * size
            pts = np.stack([half + radii * np.cos(angles), half + radii * np.sin(angles)], 1).astype(np.int32)
            cv2.fillPoly(tile, [pts], 1)
        elif kind == "rectangle":
            box = cv2.boxPoints(((half, half), (2 * size * rng.uniform(0.5, 1.0), 2 * size * rng.uniform(0.3, 1.0)),
                                 float(rng.uniform(0, 90))))
            cv2.fillPoly(tile, [box.astype(np.int32)], 1)
        else:  # thin structure: a bar 2-4 px wide
            ang = rng.uniform(0, np.pi)
            d = np.array([np.cos(ang), np.sin(ang)]) * half * 0.95
            cv2.line(tile, tuple(int(a) for a in (half - d[0], half - d[1])),
                     tuple(int(a) for a in (half + d[0], half + d[1])), 1, int(rng.integers(2, 5)))
        tone = rng.random()
        mean = rng.uniform(0.06, 0.15) if tone < 0.25 else (rng.uniform(0.8, 0.95) if tone < 0.5 else rng.uniform(0.3, 0.7))
        obj_albedo = texture(rng, tile.shape[0], tile.shape[1], mean, contrast)
        z_c = rng.uniform(0.5, 1.3)
        sx, sy = rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6)
        cx0, cy0 = rng.uniform(0, width), rng.uniform(0, height)
        vx, vy = rng.uniform(-40, 40) * width / 640, rng.uniform(-20, 20) * height / 480
        vz = rng.uniform(-0.15, 0.15)
        # drift: wrap sideways, bounce in depth within 0.5..1.3 m
        cx = (cx0 + vx * t) % (width + 2 * half) - half
        cy = (cy0 + vy * t) % (height + 2 * half) - half
        zz = (z_c - 0.5 + vz * t) % 1.6
        z_c = 0.5 + (zz if zz <= 0.8 else 1.6 - zz)
        x0, y0 = int(round(cx)) - half, int(round(cy)) - half
        xa, ya = max(0, x0), max(0, y0)
        xb, yb = min(width, x0 + tile.shape[1]), min(height, y0 + tile.shape[0])
        if xa >= xb or ya >= yb:
            continue
        sub = (slice(ya, yb), slice(xa, xb))
        mask = tile[ya - y0:yb - y0, xa - x0:xb - x0] > 0
        # plane through the object centre with normal (sx, sy, 1)
        uc, vc = (cx - geometry.cx_camera) / geometry.focal_px, (cy - geometry.cy) / geometry.focal_px
        c0 = z_c * (1.0 + sx * uc + sy * vc)
        zobj = c0 / (1.0 + sx * u[None, xa:xb] + sy * v[ya:yb, None])
        zobj = np.clip(zobj, 0.45, 1.9)
        front = mask & (zobj < depth[sub])
        depth[sub] = np.where(front, zobj, depth[sub])
        albedo[sub] = np.where(front, obj_albedo[ya - y0:yb - y0, xa - x0:xb - x0], albedo[sub])
        oid[sub] = np.where(front, k + 1, oid[sub])
        scat[sub] = np.where(front, 1.0 if k % 3 == 0 else 0.0, scat[sub])
    return depth, albedo, oid, scat


# --------------------------------------------------------------------------------------- analytic

def _analytic_albedo(rng, width, height, p):
    return texture(rng, height, width, float(p["albedo"]), float(p["texture"]))


def _dz(p: dict[str, Any]) -> float:
    return float(p["motion"]) * _wave(float(p["t"]))


def _plane(width, height, geometry, rng, p):
    z = float(p.get("depth", 1.0)) + _dz(p)
    depth = np.full((height, width), z)
    return depth, _analytic_albedo(rng, width, height, p), np.zeros((height, width), np.int32), _central_ellipse(width, height)


def _tilted_plane(width, height, geometry, rng, p):
    z = float(p.get("depth", 1.0)) + _dz(p)
    depth = _plane_depth(geometry, width, height, z, float(p.get("slope", 0.6)), float(p.get("slope_y", 0.0)))
    return np.clip(depth, 0.4, 2.0), _analytic_albedo(rng, width, height, p), np.zeros((height, width), np.int32), \
        _central_ellipse(width, height)


def _steps(width, height, geometry, rng, p):
    n = int(p.get("steps", 4))
    if n < 1:
        raise ValueError(f"steps scene: steps must be >= 1, got {n}")
    ramp = np.linspace(float(p.get("near", 0.6)), float(p.get("far", 1.6)), n)
    # alternate near and far steps so both kinds of depth edge occur (projector shadows and
    # camera occlusions)
    order = np.empty(n, dtype=np.int64)
    order[0::2] = np.arange((n + 1) // 2)
    order[1::2] = np.arange(n - 1, (n + 1) // 2 - 1, -1)
    depths = ramp[order] + _dz(p)
    band = np.minimum(np.arange(width) * n // width, n - 1)
    depth = np.broadcast_to(depths[band][None, :], (height, width)).copy()
    oid = np.broadcast_to(band[None, :].astype(np.int32), (height, width)).copy()
    return depth, _analytic_albedo(rng, width, height, p), oid, _central_ellipse(width, height)


def _sphere(width, height, geometry, rng, p):
    u, v = geometry.rays(width, height)
    uu, vv = np.meshgrid(u, v)
    cz = float(p.get("depth", 1.0))
    radius = _radius(p, width, height, geometry, cz, 0.3)
    cx = float(p.get("motion", 0.05)) * 2.0 * _wave(float(p["t"]))
    bg = float(p.get("background", 1.6))
    # |Z*(u, v, 1) - (cx, 0, cz)|^2 = R^2
    a = uu**2 + vv**2 + 1.0
    b = -2.0 * (uu * cx + cz)
    c = cx**2 + cz**2 - radius**2
    disc = b**2 - 4 * a * c
    with np.errstate(invalid="ignore"):
        zs = (-b - np.sqrt(disc)) / (2 * a)
    hit = disc > 0
    depth = np.where(hit, zs, bg)
    oid = hit.astype(np.int32)
    return depth, _analytic_albedo(rng, width, height, p), oid, hit


def _radius(p, width, height, geometry, depth, fraction):
    """``p["radius"]`` metres, or by default ``fraction`` of the smaller image side at ``depth``."""
    if p.get("radius") is not None:
        return float(p["radius"])
    return fraction * min(width, height) / geometry.focal_px * depth


def _v_groove(width, height, geometry, rng, p):
    u, _ = geometry.rays(width, height)
    opening = float(p.get("angle_deg", 90.0))
    if not 10.0 <= opening < 180.0:
        raise ValueError(f"v-groove scene: angle_deg must be in [10, 180), got {opening}")
    k = 1.0 / math.tan(math.radians(opening) / 2.0)
    zc = float(p.get("depth", 1.2)) + _dz(p)
    depth = np.broadcast_to((zc / (1.0 + k * np.abs(u)))[None, :], (height, width))
    return np.clip(depth, 0.4, 2.0), _analytic_albedo(rng, width, height, p), np.zeros((height, width), np.int32), \
        _central_ellipse(width, height)


def _bowl(width, height, geometry, rng, p):
    u, v = geometry.rays(width, height)
    uu, vv = np.meshgrid(u, v)
    zs = float(p.get("depth", 1.2)) + _dz(p)
    radius = _radius(p, width, height, geometry, zs, 0.35)
    rim = (uu * zs) ** 2 + (vv * zs) ** 2 < radius**2
    a = uu**2 + vv**2 + 1.0
    with np.errstate(invalid="ignore"):
        far = (zs + np.sqrt(zs**2 - a * (zs**2 - radius**2))) / a
    depth = np.where(rim, far, zs)
    return depth, _analytic_albedo(rng, width, height, p), np.zeros((height, width), np.int32), rim


def _scattering_scene(width, height, geometry, rng, p):
    depth, albedo, oid, _ = _tilted_plane(width, height, geometry, rng, {**p, "slope": p.get("slope", 0.3)})
    region = np.zeros((height, width), np.uint8)
    for _ in range(4):
        cv2.ellipse(region, (int(rng.integers(width // 6, 5 * width // 6)), int(rng.integers(height // 6, 5 * height // 6))),
                    (int(rng.integers(width // 12, width // 6)), int(rng.integers(height // 12, height // 5))),
                    float(rng.uniform(0, 180)), 0, 360, 1, -1)
    return depth, albedo, oid, region > 0


_SCENES: dict[str, tuple[Callable[..., Any], dict[str, Any]]] = {
    "flying": (_flying, {"objects": 12}),
    "plane": (_plane, {"depth": 1.0}),
    "tilted-plane": (_tilted_plane, {"depth": 1.0, "slope": 0.6, "slope_y": 0.0}),
    "steps": (_steps, {"steps": 4, "near": 0.6, "far": 1.6}),
    "sphere": (_sphere, {"radius": None, "depth": 1.0, "background": 1.6}),
    "v-groove": (_v_groove, {"angle_deg": 90.0, "depth": 1.2, "interreflection": 1.0}),
    "bowl": (_bowl, {"radius": None, "depth": 1.2, "interreflection": 1.0}),
    "scattering": (_scattering_scene, {"depth": 1.0, "slope": 0.3, "scattering": 0.8}),
}


#: Smallest camera (width, height) in pixels of a scene generator, where it is more than 2 x 2:
#: ``scattering`` draws its scattering regions as ellipses with semi-axes of width/12 .. width/6
#: and height/12 .. height/5 pixels (integer bounds, upper bound excluded), an empty range below 6
#: columns or 5 rows.
_MIN_SIZE: dict[str, tuple[int, int]] = {"scattering": (6, 5)}


def scene_names() -> list[str]:
    """Names `make_scene` accepts."""
    return sorted(_SCENES)


def min_scene_size(name: str) -> tuple[int, int]:
    """Smallest camera (width, height) in pixels on which scene ``name`` can be built (2 x 2 for
    most; ValueError for an unknown name)."""
    if name not in _SCENES:
        raise ValueError(f"unknown scene {name!r}; valid scenes: {', '.join(scene_names())}")
    return _MIN_SIZE.get(name, (2, 2))


def make_scene(name: str, width: int = 640, height: int = 480, *, seed: int = 0, geometry: Geometry | None = None,
               **params: Any) -> Scene:
    """Build scene ``name`` for a ``width`` x ``height`` camera; deterministic given ``seed`` and ``t``.

    geometry defaults to `Geometry.default(width, height)`.  Parameters: see the module docstring;
    unknown names raise ValueError.
    """
    if name not in _SCENES:
        raise ValueError(f"unknown scene {name!r}; valid scenes: {', '.join(scene_names())}")
    need_w, need_h = min_scene_size(name)
    if int(width) < need_w or int(height) < need_h:
        raise ValueError(f"scene {name!r} needs at least {need_w}x{need_h} pixels, got {width}x{height}")
    build, defaults = _SCENES[name]
    allowed = {**_COMMON, **defaults}
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(f"scene {name!r}: unknown parameter(s) {unknown}; accepted: {sorted(allowed)}")
    p = {**allowed, **params}
    scat_strength = p["scattering"] if p["scattering"] is not None else 0.0
    inter = p["interreflection"] if p["interreflection"] is not None else 0.0
    if not 0.0 <= float(scat_strength) <= 1.0:
        raise ValueError(f"scene {name!r}: scattering strength must be in [0, 1], got {scat_strength}")
    if float(inter) < 0:
        raise ValueError(f"scene {name!r}: interreflection strength must be >= 0, got {inter}")
    if float(p["scattering_sigma"]) <= 0:
        raise ValueError(f"scene {name!r}: scattering_sigma must be > 0 pixels, got {p['scattering_sigma']}")
    if not 0.0 <= float(p["texture"]) <= 1.0:
        raise ValueError(f"scene {name!r}: texture contrast must be in [0, 1], got {p['texture']}")
    if int(p["bounces"]) != p["bounces"] or int(p["bounces"]) < 1:
        raise ValueError(f"scene {name!r}: bounces must be an integer >= 1, got {p['bounces']}")
    if not float(p["gloss"]) >= 0:
        raise ValueError(f"scene {name!r}: gloss must be >= 0, got {p['gloss']}")
    if int(p["gi_patch"]) != p["gi_patch"] or int(p["gi_patch"]) < 1:
        raise ValueError(f"scene {name!r}: gi_patch must be an integer >= 1 pixel, got {p['gi_patch']}")
    geometry = geometry or Geometry.default(int(width), int(height))
    rng = np.random.default_rng(int(seed))
    depth, albedo, oid, region = build(int(width), int(height), geometry, rng, p)
    scattering = region.astype(np.float32) * float(scat_strength)
    return build_scene(
        name, depth, albedo, oid, geometry, scattering=scattering,
        scattering_sigma=float(p["scattering_sigma"]) if scat_strength > 0 else 0.0,
        interreflection=float(inter), t=float(p["t"]), seed=int(seed), params=dict(params),
        gi_patch=int(p["gi_patch"]), bounces=int(p["bounces"]), gloss=float(p["gloss"]),
    )

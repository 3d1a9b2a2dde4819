"""Image formation, eq. (1): ``I_i = W[P_i] * A + I_a + N`` for a rectified projector-camera pair.

`capture` renders ANY stack of projector images (code patterns, masked re-projection frames, dot
patterns); `capture_code` renders a code at fixed total exposure plus its two calibration frames.

Projector frames: shape (m, Hp, Wp) or (m, Wp) (column profiles, the same on every row).
uint8 values are 0..255 (divided by 255); float values must already be in [0, 1]; other integer
types must hold 0..255.  Hp must equal the camera height (rows are shared) or be 1.  Wp may be
smaller than the projector (columns beyond it are dark) but not larger.

Camera pixel (y, x) sees projector row y at column ``scene.column[y, x]`` (nearest column
``scene.column_int`` by default, see `CameraModel.sampling`) and no projector light where
``scene.lit`` is False.  Defocus blurs the pattern in projector space before warping; scattering
and inter-reflection are computed from the warped frames actually projected.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..capture import CodedCapture, NoiseModel, dtype_for_bits
from ..codes import Code
from ._kernels import expose, warp_linear, warp_nearest
from .camera import CameraModel
from .scene import Scene


def _as_rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, (int, np.integer)):
        return np.random.default_rng(rng)
    raise ValueError(f"rng must be a numpy Generator or an int seed, got {type(rng).__name__}")


def normalise_projector_frames(frames: np.ndarray, height: int, projector_width: int) -> np.ndarray:
    """Projector frames as float32 (m, Hp, Wp) in [0, 1]; see the module docstring for accepted input."""
    p = np.asarray(frames)
    if p.ndim == 2:
        p = p[:, None, :]
    if p.ndim != 3:
        raise ValueError(f"projector frames must have shape (m, Hp, Wp) or (m, Wp), got {p.shape}")
    m, hp, wp = p.shape
    if m < 1 or wp < 1:
        raise ValueError(f"projector frames must hold at least one frame and one column, got {p.shape}")
    if hp not in (1, height):
        raise ValueError(f"projector frames have {hp} rows; expected {height} (camera rows) or 1")
    if wp > projector_width:
        raise ValueError(f"projector frames are {wp} columns wide but the projector has {projector_width} columns")
    if p.dtype == np.uint8:
        out = p.astype(np.float32) * np.float32(1.0 / 255.0)
    elif np.issubdtype(p.dtype, np.integer):
        if p.size and (p.min() < 0 or p.max() > 255):
            raise ValueError(f"integer projector frames must hold 0..255, got {p.min()}..{p.max()}")
        out = p.astype(np.float32) * np.float32(1.0 / 255.0)
    elif np.issubdtype(p.dtype, np.floating) or p.dtype == np.bool_:
        out = p.astype(np.float32)
        if out.size and not (np.isfinite(out).all() and out.min() >= 0.0 and out.max() <= 1.0 + 1e-6):
            raise ValueError(f"float projector frames must be in [0, 1], got {np.nanmin(out)}..{np.nanmax(out)}")
    else:
        raise ValueError(f"projector frames must be uint8, integer or float, got dtype {p.dtype}")
    return np.ascontiguousarray(out)


def defocus(patterns: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur of (m, Hp, Wp) float32 projector frames by ``sigma`` projector pixels."""
    if sigma <= 0:
        return patterns
    out = np.empty_like(patterns)
    sigma_y = sigma if patterns.shape[1] > 1 else 1e-6
    for i in range(patterns.shape[0]):
        blurred = cv2.GaussianBlur(patterns[i], (0, 0), sigmaX=float(sigma), sigmaY=float(sigma_y),
                                   borderType=cv2.BORDER_REPLICATE)
        out[i] = blurred.reshape(patterns.shape[1:])
    return out


def projector_irradiance(scene: Scene, projector_frames: np.ndarray, camera: CameraModel) -> np.ndarray:
    """(m, H, W) float32 projector irradiance at each camera pixel (0..1 per unit pattern), GI included."""
    h = scene.height
    patterns = normalise_projector_frames(projector_frames, h, int(scene.geometry.projector_width))
    patterns = defocus(patterns, camera.defocus_sigma)
    row_of = (np.arange(h, dtype=np.int32) if patterns.shape[1] == h else np.zeros(h, dtype=np.int32))
    if camera.sampling == "linear":
        e = warp_linear(patterns, scene.column, row_of)
    else:
        e = warp_nearest(patterns, scene.column_int, row_of)
    if scene.has_scattering or scene.interreflection is not None:
        e = scene.indirect_light(e)
    return e


#: A rows= render of at most this many samples (frames x rows x columns) runs in numpy: a parallel
#: kernel's start-up dominates such small jobs (the few rows of a masked EDC round).
SMALL_RENDER = 1 << 21


def _warp_nearest_small(patterns: np.ndarray, column_int: np.ndarray, row_of: np.ndarray) -> np.ndarray:
    """`warp_nearest` (same result); numpy for small jobs."""
    m, _, wp = patterns.shape
    if m * column_int.size > SMALL_RENDER:
        return warp_nearest(patterns, column_int, row_of)
    ok = (column_int >= 0) & (column_int < wp)
    e = patterns[:, row_of[:, None], np.clip(column_int, 0, wp - 1)]
    return np.where(ok[None], e, np.float32(0.0)).astype(np.float32)


def _expose_numpy(e: np.ndarray, albedo: np.ndarray, scale_projector: float, ambient_level: float,
                  normals: np.ndarray, sigma_r2: float, sigma_s2: float, levels: float, dtype) -> np.ndarray:
    """`expose` in numpy (float64 arithmetic like the kernel), for small renders."""
    clean = np.maximum(albedo.astype(np.float64)[None] * (scale_projector * e.astype(np.float64) + ambient_level), 0.0)
    noisy = clean + np.sqrt(sigma_r2 + sigma_s2 * clean) * normals
    return np.clip(np.floor(noisy * levels + 0.5), 0.0, levels).astype(dtype)


def has_global_illumination(scene: Scene) -> bool:
    """True when a pixel's light depends on other pixels (scattering or inter-reflection)."""
    return bool(scene.has_scattering or (scene.interreflection is not None and scene.interreflection.strength > 0))


def capture(scene: Scene, projector_frames: np.ndarray, camera: CameraModel, *,
            rng: np.random.Generator | int | None, exposure: float | None = None,
            rows: np.ndarray | None = None, extra_irradiance: np.ndarray | None = None) -> np.ndarray:
    """Camera frames (m, H, W) of ``scene`` lit by ``projector_frames`` (eq. 1 plus noise and ADC).

    exposure: per-frame exposure (relative units), default ``camera.exposure``; light and ambient
    scale linearly with it.  rng: numpy Generator (or int seed) for the noise.  rows: optional
    camera rows to render (int array); the result is then (m, len(rows), W).  Only exact without
    global illumination (a pixel's light then depends on its own projector row alone): a scene
    with scattering or inter-reflection raises ValueError.  extra_irradiance: optional float32
    (m, H, W) light of other projectors (same units as the own projector's irradiance, e.g. other
    devices in the room), added before noise and ADC (only its ``rows`` are used with ``rows``).
    Returns uint8 frames for 8-bit cameras, uint16 (0..2**bits-1) otherwise.
    """
    t = camera.exposure if exposure is None else exposure
    if not (np.isfinite(t) and t > 0):
        raise ValueError(f"capture: exposure must be > 0, got {t}")
    if extra_irradiance is not None:
        want = (int(np.shape(projector_frames)[0]), scene.height, scene.width)
        if np.shape(extra_irradiance) != want:  # it broadcast silently, or failed on the rows path
            raise ValueError(f"capture: extra_irradiance must be (m, H, W) = {want}, got shape {np.shape(extra_irradiance)}")
    gen = _as_rng(rng)
    albedo = scene.albedo
    if rows is None:
        e = projector_irradiance(scene, projector_frames, camera)
    else:
        if has_global_illumination(scene):
            raise ValueError("capture: rows= needs a scene without global illumination (scattering, inter-reflection)")
        r = np.asarray(rows, dtype=np.int32)
        if r.ndim != 1 or (r.size and (r.min() < 0 or r.max() >= scene.height)):
            raise ValueError(f"capture: rows must be camera rows 0..{scene.height - 1}, got {r!r}")
        p = np.asarray(projector_frames)
        wp = int(scene.geometry.projector_width)
        if camera.defocus_sigma <= 0 and p.ndim == 3 and p.shape[1] == scene.height:
            # no blur across rows: normalise only the projector rows the camera rows see
            patterns = normalise_projector_frames(p[:, r], r.size, wp)
            row_of = np.arange(r.size, dtype=np.int32)
        else:
            patterns = defocus(normalise_projector_frames(p, scene.height, wp), camera.defocus_sigma)
            row_of = r if patterns.shape[1] == scene.height else np.zeros(r.size, dtype=np.int32)
        if camera.sampling == "linear":
            e = warp_linear(patterns, np.ascontiguousarray(scene.column[r]), row_of)
        else:
            e = _warp_nearest_small(patterns, np.ascontiguousarray(scene.column_int[r]), row_of)
        albedo = np.ascontiguousarray(albedo[r])
        if extra_irradiance is not None:
            e = np.ascontiguousarray(e + np.asarray(extra_irradiance, np.float32)[:, r])
        if e.size <= SMALL_RENDER:
            normals = gen.standard_normal(e.shape, dtype=np.float32)
            return _expose_numpy(e, albedo, float(t * camera.projector), float(t * camera.ambient), normals,
                                 float(camera.sigma_r**2), float(camera.sigma_s**2), float(camera.levels),
                                 dtype_for_bits(camera.bits))
    if rows is None and extra_irradiance is not None:
        e = np.ascontiguousarray(e + np.asarray(extra_irradiance, np.float32))
    normals = gen.standard_normal(e.shape, dtype=np.float32)
    out = np.empty(e.shape, dtype=dtype_for_bits(camera.bits))
    expose(e, albedo, float(t * camera.projector), float(t * camera.ambient), normals,
           float(camera.sigma_r**2), float(camera.sigma_s**2), float(camera.levels), out)
    return out


def code_profiles(code: Code, projector_width: int, *, stripe: int = 1) -> np.ndarray:
    """(n, projector_width) float32 column profiles of ``code``: column x sends row ``x // stripe``.

    N-ary symbols s are rendered at intensity ``s / (q - 1)``.  Columns beyond the code's
    ``size * stripe`` are dark.
    """
    if stripe < 1:
        raise ValueError(f"stripe must be >= 1, got {stripe}")
    if projector_width < 1:
        raise ValueError(f"projector_width must be >= 1, got {projector_width}")
    rows = np.arange(projector_width) // stripe
    covered = rows < code.size
    symbols = np.zeros((code.n, projector_width), dtype=np.float32)
    symbols[:, covered] = code.codebook[rows[covered]].T.astype(np.float32) / np.float32(code.q - 1)
    return symbols


def capture_code(scene: Scene, code: Code, camera: CameraModel, *, rng: np.random.Generator | int | None,
                 stripe: int = 1) -> CodedCapture:
    """Capture ``code`` at fixed total exposure: n frames of exposure ``camera.total_exposure / n``.

    The white (all on) and black (all off) calibration frames use the same per-frame exposure and
    are captured after the code frames from the same noise stream.  Raises ValueError if the scene
    sees projector columns the code (times ``stripe``) does not cover.

    A simulated capture is the one coded-capture type (`edge.capture.CodedCapture`): frames,
    white, black, code, stripe, bit_depth = ADC bits, frame_exposure (relative units, n + 2 equal
    values at fixed total exposure), noise (the camera's sigma_r, sigma_s), camera.
    """
    if not isinstance(code, Code):
        raise ValueError(f"capture_code: expected an edge.codes.Code, got {type(code).__name__}")
    if int(stripe) != stripe or stripe < 1:
        raise ValueError(f"capture_code: stripe must be a positive integer, got {stripe}")
    wp = int(scene.geometry.projector_width)
    covered = code.size * int(stripe)
    seen = scene.column_int[scene.lit]
    if seen.size and int(seen.max()) >= covered:
        raise ValueError(
            f"code {code.name!r} with stripe {stripe} covers projector columns 0..{covered - 1}, but scene "
            f"{scene.name!r} sees columns up to {int(seen.max())}; use a larger stripe or a longer code"
        )
    profiles = code_profiles(code, wp, stripe=int(stripe))
    stack = np.concatenate([profiles, np.ones((1, wp), np.float32), np.zeros((1, wp), np.float32)], axis=0)
    t = camera.frame_exposure(code.n)
    frames = capture(scene, stack, camera, rng=rng, exposure=t)
    return CodedCapture(frames=frames[:-2], white=frames[-2], black=frames[-1], code=code, stripe=int(stripe),
                        bit_depth=camera.bits, frame_exposure=np.full(code.n + 2, t), exposure_unit="relative",
                        noise=NoiseModel(float(camera.sigma_r), float(camera.sigma_s)), camera=camera)

"""Global illumination: one-bounce inter-reflection and short-range sub-surface scattering.

Both act on the projector irradiance actually reaching the scene in each frame, so a projector
column that is switched off contributes neither direct nor indirect light.

Inter-reflection (`Interreflection`): the camera-visible surface is cut into square patches of
``patch`` pixels.  Patch j reflects radiance ``B_j = mean(albedo * E)`` over the patch (E: direct
projector irradiance, 0..1); patch i receives ``sum_j F_ij B_j`` with the diffuse form factor

    F_ij = A_j * max(0, n_i . w_ij) * max(0, n_j . -w_ij) / (pi * max(r_ij**2, A_j))

(w_ij the unit vector from i to j, A_j the patch's surface area).  Mutual visibility is assumed,
which is exact for the concave scenes it is meant for (V-groove, bowl); for flat or convex parts
the cosine terms vanish.  The indirect irradiance is upsampled bilinearly to pixels and multiplied
by ``strength`` (1 = physical).

Glossy ("specular-ish") surfaces (``gloss`` = g > 0): patch j reflects the projector light into a
normalised Phong lobe around the mirror direction r_j of the projector ray instead of uniformly,
``F_ij(gloss) = F_ij * (g + 2) / 2 * max(0, r_j . w_ji)**g`` -- the light of a patch lands on a few
receivers, so the indirect light a pixel gets depends on WHICH columns are lit (it no longer
averages out over high-frequency patterns).  Several bounces (``bounces`` = b): the light received
is reflected again with the patch's mean albedo, ``sum_{k=1..b} (strength * F * diag(albedo))**(k-1)
strength * F B``.

Sub-surface scattering (`scatter`): inside a region R with strength map s (0..1), light entering
at one point leaves within a Gaussian footprint of ``sigma`` pixels:
``E' = (1 - s) * E + s * G_sigma * (E * [R])`` on R, E elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .geometry import Geometry


@dataclass(frozen=True, eq=False)
class Interreflection:
    """Coarse one-bounce light transport of a scene.

    Attributes:
        patch: patch side in pixels.
        shape: camera image (H, W).
        form_factor: (P, P) float32, P = ceil(H/patch) * ceil(W/patch); row i = receiving patch.
        strength: multiplier of the indirect term (1 = physical).
        bounces: light bounces summed (1 = one bounce).
        patch_albedo: (P,) float32 mean albedo per patch (used from the second bounce on).
    """

    patch: int
    shape: tuple[int, int]
    form_factor: np.ndarray
    strength: float
    bounces: int = 1
    patch_albedo: np.ndarray | None = None

    @property
    def grid(self) -> tuple[int, int]:
        h, w = self.shape
        return -(-h // self.patch), -(-w // self.patch)

    def patch_mean(self, images: np.ndarray) -> np.ndarray:
        """(m, H, W) -> (m, P) mean over each patch (edge patches average their pixels only)."""
        m = images.shape[0]
        h, w = self.shape
        gh, gw = self.grid
        padded = np.zeros((m, gh * self.patch, gw * self.patch), dtype=np.float32)
        padded[:, :h, :w] = images
        sums = padded.reshape(m, gh, self.patch, gw, self.patch).sum(axis=(2, 4))
        counts = np.zeros((gh * self.patch, gw * self.patch), dtype=np.float32)
        counts[:h, :w] = 1.0
        n = counts.reshape(gh, self.patch, gw, self.patch).sum(axis=(1, 3))
        return (sums / n).reshape(m, gh * gw).astype(np.float32)

    def indirect(self, radiance: np.ndarray) -> np.ndarray:
        """Indirect irradiance (m, H, W) float32 from per-pixel outgoing radiance (m, H, W)."""
        m = radiance.shape[0]
        h, w = self.shape
        gh, gw = self.grid
        received = (self.patch_mean(radiance) @ self.form_factor.T) * np.float32(self.strength)
        bounce = received
        for _ in range(1, self.bounces):
            albedo = self.patch_albedo if self.patch_albedo is not None else np.float32(1.0)
            bounce = ((bounce * albedo) @ self.form_factor.T) * np.float32(self.strength)
            received = received + bounce
        out = np.empty((m, h, w), dtype=np.float32)
        size = (gw * self.patch, gh * self.patch)
        for i in range(m):
            up = cv2.resize(received[i].reshape(gh, gw), size, interpolation=cv2.INTER_LINEAR)
            out[i] = up[:h, :w]
        return out


def surface_points(depth_m: np.ndarray, geometry: Geometry) -> np.ndarray:
    """(H, W, 3) float64 camera-frame points (metres) of a depth map (NaN where depth is NaN)."""
    h, w = depth_m.shape
    u, v = geometry.rays(w, h)
    z = depth_m.astype(np.float64)
    return np.stack([u[None, :] * z, v[:, None] * z, z], axis=-1)


def surface_normals(points: np.ndarray) -> np.ndarray:
    """(H, W, 3) unit normals from finite differences of the point map, facing the camera."""
    dx = np.gradient(points, axis=1)
    dy = np.gradient(points, axis=0)
    n = np.cross(dx, dy)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / norm
    flip = (n * points).sum(axis=-1) > 0
    n[flip] *= -1.0
    return n


def build_interreflection(depth_m: np.ndarray, geometry: Geometry, *, strength: float = 1.0,
                          patch: int = 16, bounces: int = 1, gloss: float = 0.0,
                          albedo: np.ndarray | None = None) -> Interreflection:
    """Inter-reflection transport of the camera-visible surface ``depth_m`` (H, W) metres.

    bounces >= 1; gloss >= 0 (0 = diffuse, see the module docstring); albedo: (H, W) for the
    per-patch albedo of the second and later bounces (default 1).
    """
    if strength < 0:
        raise ValueError(f"interreflection strength must be >= 0, got {strength}")
    if int(bounces) != bounces or bounces < 1:
        raise ValueError(f"interreflection bounces must be an integer >= 1, got {bounces}")
    if not gloss >= 0:
        raise ValueError(f"interreflection gloss must be >= 0, got {gloss}")
    h, w = depth_m.shape
    pts = surface_points(depth_m, geometry)
    nrm = surface_normals(pts)
    finite = np.isfinite(pts).all(axis=-1) & np.isfinite(nrm).all(axis=-1)
    ray = pts / np.linalg.norm(pts, axis=-1, keepdims=True)
    cos_view = np.abs((nrm * ray).sum(axis=-1))
    pixel_area = (depth_m.astype(np.float64) / geometry.focal_px) ** 2 / np.maximum(cos_view, 0.1)
    pixel_area = np.where(finite, pixel_area, 0.0)
    gh, gw = -(-h // patch), -(-w // patch)

    def block_sum(a: np.ndarray) -> np.ndarray:
        pad = np.zeros((gh * patch, gw * patch) + a.shape[2:], dtype=np.float64)
        pad[:h, :w] = np.where(finite.reshape(finite.shape + (1,) * (a.ndim - 2)), a, 0.0)
        return pad.reshape(gh, patch, gw, patch, *a.shape[2:]).sum(axis=(1, 3)).reshape(gh * gw, *a.shape[2:])

    count = block_sum(finite.astype(np.float64))
    area = block_sum(pixel_area)
    safe = np.maximum(count, 1.0)
    p = block_sum(pts) / safe[:, None]
    n = block_sum(nrm)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    # pairwise terms through matrix products (no (P, P, 3) temporaries):
    # n_i . (p_j - p_i) = (N P^T)_ij - n_i . p_i ;  |p_j - p_i|^2 = |p_i|^2 + |p_j|^2 - 2 p_i . p_j
    npt = n @ p.T
    own = (n * p).sum(axis=1)
    sq = (p * p).sum(axis=1)
    r2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * (p @ p.T), 0.0)
    r = np.sqrt(np.maximum(r2, 1e-18))
    cos_i = np.maximum(0.0, (npt - own[:, None]) / r)
    cos_j = np.maximum(0.0, (npt.T - own[None, :]) / r)
    f = area[None, :] * cos_i * cos_j / (np.pi * np.maximum(r2, area[None, :]))
    if gloss > 0:
        # mirror direction of the projector ray at each source patch j (projector centre (B, 0, 0))
        inc = p - np.array([geometry.baseline_m, 0.0, 0.0])
        inc /= np.maximum(np.linalg.norm(inc, axis=-1, keepdims=True), 1e-12)
        mirror = inc - 2.0 * (inc * n).sum(axis=1, keepdims=True) * n
        # r_j . w_ji with w_ji = (p_i - p_j) / r_ij
        rp = p @ mirror.T  # (i, j): p_i . r_j
        own_r = (mirror * p).sum(axis=1)
        cos_lobe = np.maximum(0.0, (rp - own_r[None, :]) / r)
        f = f * ((gloss + 2.0) / 2.0) * cos_lobe ** gloss
    np.fill_diagonal(f, 0.0)
    empty = count == 0
    f[empty, :] = 0.0
    f[:, empty] = 0.0
    patch_albedo = None
    if albedo is not None and bounces > 1:
        patch_albedo = (block_sum(np.asarray(albedo, dtype=np.float64)) / safe).astype(np.float32)
    return Interreflection(patch=patch, shape=(h, w), form_factor=f.astype(np.float32), strength=float(strength),
                           bounces=int(bounces), patch_albedo=patch_albedo)


def scatter(irradiance: np.ndarray, strength_map: np.ndarray, sigma_px: float) -> np.ndarray:
    """Sub-surface scattering of (m, H, W) irradiance inside the region ``strength_map > 0``.

    strength_map: (H, W) float32 in [0, 1]; sigma_px: Gaussian footprint (pixels).  Returns a new
    float32 array; pixels outside the region are unchanged.
    """
    region = (strength_map > 0).astype(np.float32)
    s = strength_map.astype(np.float32)
    out = irradiance.astype(np.float32, copy=True)
    for i in range(out.shape[0]):
        blurred = cv2.GaussianBlur(out[i] * region, (0, 0), sigmaX=sigma_px, sigmaY=sigma_px,
                                   borderType=cv2.BORDER_CONSTANT)
        out[i] = np.where(region > 0, (1.0 - s) * out[i] + s * blurred, out[i])
    return out

"""Joint (decorrelating) matched filter: estimate every known device's light, then detect the own one.

The plain matched filter (`edge.source.matched_filter.despread`) correlates each L-slot window with
the own template and *rejects* the whole symbol when foreign light bends the correlation below the
threshold: under overlap the own signal is lost.  In a room the other devices' codes are known (the
claim table), only their clock offsets are not.  Model of one pixel over a stack of m symbols
(m * L slots, my clock)::

    r = sum_i a_i * own_i + c * 1 + sum_k sum_j v_kj * u_kj(tau_k) + noise

own_i: my code in the slots of my symbol i (0 elsewhere); c: ambient; u_kj: the slots device k's
symbol j (its code, shifted by its offset tau_k, integrated over my slots: fractional offsets
give overlap weights) lights; v_kj >= 0 its unknown level at this pixel (its pattern x power x
albedo).  The design matrix X (m L x K) is the same for every pixel of the stack, so one
pseudo-inverse gives all amplitudes by a matrix product; the own amplitudes a_i are decorrelated
from ambient and from every device in the model whatever their level.

Offsets: `estimate_offsets` searches each foreign device's offset on a 1/``steps`` slot grid over
one symbol (its symbol values are free unknowns, so the offset matters modulo L) by the residual
energy of the fit on a sample of pixels: devices added one by one on a 1/4-slot grid, then each
re-searched over the whole grid against all the others until no offset changes (at most 3 passes);
restarted from up to 4 rotations of the order the devices are added in, the best fit kept.

Detection (`detect`): the noise sigma of each pixel is measured from the fit residual (with the
residual degrees of freedom), the noise of each own amplitude is ``sigma * |g_i|`` (g_i the
pseudo-inverse row: noise gain of that symbol).  A symbol is "on" when its amplitude exceeds both
half the pixel's reference level (its white symbol) and ``z`` amplitude-noise sigmas; a pixel whose
reference does not exceed ``2 z`` sigmas is not lit by the own device (nothing detected).  Model
mismatch (a wrong offset, an unknown device) leaves energy in the residual, which raises sigma
and so the threshold: measured interference makes the detector more careful, not wrong.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..codes.source import SourceCode, source_code

#: z of the detection threshold (one-sided Gaussian false-alarm rate ~1.3e-3 per symbol)
DEFAULT_Z = 3.0


def foreign_columns(code: SourceCode, n_slots: int, offset: float) -> np.ndarray:
    """float64 (n_slots, J): slots of my window lit by each symbol j of a foreign device whose slot q
    covers my time [q + offset, q + offset + 1) (overlap-weighted); symbols that light nothing dropped."""
    L = code.length
    j_lo = int(np.floor(-offset / L)) - 1
    j_hi = int(np.ceil((n_slots - offset) / L)) + 1
    t = np.arange(n_slots, dtype=np.float64)[:, None]
    cols = []
    for j in range(j_lo, j_hi + 1):
        q = j * L + np.arange(L, dtype=np.float64)[None, :]
        start = q + offset
        ov = np.clip(np.minimum(t + 1, start + 1) - np.maximum(t, start), 0.0, 1.0)  # (n_slots, L)
        col = ov @ code.bits.astype(np.float64)
        if col.any():
            cols.append(col)
    return np.stack(cols, axis=1) if cols else np.zeros((n_slots, 0))


def design(own: SourceCode, foreign: Sequence[SourceCode], offsets: Sequence[float], n_symbols: int) -> np.ndarray:
    """(n_symbols * L, n_symbols + 1 + sum_k J_k) design matrix: own symbols, ambient, foreign symbols."""
    if len(offsets) != len(foreign):  # zip() would drop the devices without an offset from the model
        raise ValueError(f"{len(foreign)} foreign codes need {len(foreign)} offsets, got {len(offsets)}")
    L = own.length
    n = n_symbols * L
    own_cols = np.zeros((n, n_symbols))
    for i in range(n_symbols):
        own_cols[i * L:(i + 1) * L, i] = own.bits
    parts = [own_cols, np.ones((n, 1))]
    for code, off in zip(foreign, offsets):
        parts.append(foreign_columns(code, n, float(off)))
    return np.concatenate(parts, axis=1)


@dataclass(frozen=True)
class JointResult:
    """amplitude: float32 (m, H, W) own-light amplitude per symbol (input units, decorrelated);
    sigma: float32 (H, W) measured per-slot noise (fit residual); gain: float64 (m,) noise gain of
    each own amplitude (|g_i|); offsets: the foreign offsets used (slots)."""

    amplitude: np.ndarray
    sigma: np.ndarray
    gain: np.ndarray
    offsets: tuple[float, ...]


def _fit(X: np.ndarray, R: np.ndarray, m: int):
    """Least squares of R (n, P) on X: own amplitudes (m, P), residual sigma (P,), own noise gains (m,)."""
    G = np.linalg.pinv(X)  # (K, n)
    theta = G @ R
    resid = R - X @ theta
    dof = max(1, X.shape[0] - np.linalg.matrix_rank(X))
    sigma = np.sqrt((resid * resid).sum(axis=0) / dof)
    return theta[:m], sigma, np.linalg.norm(G[:m], axis=1)


def estimate_offsets(slots: np.ndarray, own: SourceCode, foreign: Sequence[SourceCode], *, steps: int = 8,
                     sample: int = 400, seed: int = 0, restarts: int = 4) -> tuple[float, ...]:
    """Offsets (slots, in [0, L)) of the foreign devices that best explain ``slots`` (m*L, ...)."""
    L = own.length
    R = np.asarray(slots, np.float64).reshape(slots.shape[0], -1)
    n = R.shape[0]
    m = n // L
    energy = R.var(axis=0)
    idx = np.argsort(energy)[::-1][: 4 * sample]  # pixels with light on them carry the information
    rng = np.random.default_rng(seed)
    if idx.size > sample:
        idx = rng.choice(idx, sample, replace=False)
    Rs = R[:, idx]
    coarse = np.arange(L * 4) / 4.0
    full = np.arange(L * steps) / float(steps)

    def search(order: list[int]) -> list[float]:
        offs = [0.0] * len(foreign)

        def best_of(k: int, grid: np.ndarray, fixed: list[int]) -> float:
            base = design(own, [foreign[i] for i in fixed], [offs[i] for i in fixed], m)
            qb = _orth(base)
            rb = Rs - qb @ (qb.T @ Rs)
            best, best_gain = offs[k], -np.inf
            for g in grid:
                fc = foreign_columns(foreign[k], n, float(g))
                fb = fc - qb @ (qb.T @ fc)
                qf = _orth(fb)
                gain = float(((qf.T @ rb) ** 2).sum())  # energy the device explains beyond the rest
                if gain > best_gain + 1e-12:
                    best, best_gain = float(g), gain
            return best

        active: list[int] = []
        for k in order:  # add the devices one by one on a 1/4-slot grid
            offs[k] = best_of(k, coarse, active)
            active.append(k)
        for _ in range(3):  # then each on the full 1/steps grid against all the others, until stable
            before = list(offs)
            for k in order:
                offs[k] = best_of(k, full, [i for i in active if i != k])
            if offs == before:
                break
        return offs

    # coordinate search can stall in a local optimum that depends on the order the devices are
    # added in: restart from up to `restarts` rotations of the order, keep the best fit
    K = len(foreign)
    best_offs, best_cost = [0.0] * K, np.inf
    for r in range(min(K, restarts)):
        order = list(range(r, K)) + list(range(r))
        offs = search(order)
        c = cost_sub(own, foreign, offs, m, Rs)
        if c < best_cost - 1e-9:
            best_offs, best_cost = offs, c
    offs = best_offs
    return tuple(offs)


def _orth(X: np.ndarray) -> np.ndarray:
    """Orthonormal basis (n, r) of the column space of X (numerically independent columns)."""
    if X.shape[1] == 0:
        return X
    q, r = np.linalg.qr(X)
    keep = np.abs(np.diag(r)) > 1e-9 * max(1.0, float(np.abs(r).max()))
    return q[:, keep]


def cost_sub(own: SourceCode, foreign: Sequence[SourceCode], offsets: Sequence[float], m: int, Rs: np.ndarray) -> float:
    """Residual energy of the fit of Rs with the given foreign devices and offsets (by projection)."""
    X = design(own, foreign, offsets, m)
    q, rr = np.linalg.qr(X)
    keep = np.abs(np.diag(rr)) > 1e-9 * max(1.0, float(np.abs(rr).max()))
    proj = q[:, keep].T @ Rs
    return float((Rs * Rs).sum() - (proj * proj).sum())


def joint_despread(slots: np.ndarray, own: "SourceCode | str", foreign: Sequence["SourceCode | str"], *,
                   offsets: Sequence[float] | None = None, steps: int = 8) -> JointResult:
    """Own amplitudes of a stack (m*L, H, W) with every known foreign device decorrelated.

    own / foreign: codes (foreign = the other members of the room); offsets: known foreign offsets
    (slots), default estimated (`estimate_offsets`).  Without foreign codes this is the plain
    least-squares matched filter (own amplitude + ambient per symbol pair).
    """
    own = source_code(own)
    foreign = [source_code(c) for c in foreign]
    f = np.asarray(slots)
    if f.ndim != 3 or f.shape[0] % own.length or f.shape[0] == 0:
        raise ValueError(f"slots must be (m*L, H, W) with L={own.length}, got shape {f.shape}")
    if any(c.length != own.length for c in foreign):
        raise ValueError(f"foreign codes must have length {own.length}, got {[c.string for c in foreign]}")
    m = f.shape[0] // own.length
    if offsets is None:
        offsets = estimate_offsets(f, own, foreign, steps=steps) if foreign else ()
    X = design(own, foreign, offsets, m)
    if X.shape[1] >= X.shape[0]:
        raise ValueError(f"{len(foreign)} foreign devices over {m} symbols of L={own.length}: "
                         f"{X.shape[1]} unknowns for {X.shape[0]} slots (use longer codes or fewer devices)")
    R = f.reshape(f.shape[0], -1).astype(np.float64)
    a, sigma, gain = _fit(X, R, m)
    h, w = f.shape[1:]
    return JointResult(a.reshape(m, h, w).astype(np.float32), sigma.reshape(h, w).astype(np.float32),
                       gain, tuple(float(o) for o in offsets))


def detect(result: JointResult, reference: np.ndarray, *, z: float = DEFAULT_Z) -> np.ndarray:
    """bool (m, H, W): own symbol "on" (see module docstring).  reference: (H, W) own level of the
    pixel (e.g. the amplitude of the stack's white symbol)."""
    noise = result.sigma[None] * result.gain[:, None, None].astype(np.float32)  # (m, H, W)
    ref = np.asarray(reference, np.float32)[None]
    lit = ref > 2 * z * noise
    return lit & (result.amplitude > np.maximum(0.5 * ref, z * noise))

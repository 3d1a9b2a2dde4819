"""Max-min-SW Gray code: a k-bit Gray code whose narrowest stripe is as wide as possible.

Gupta et al. (CVPR 2011, "Structured light 3D scanning in the presence of global illumination")
use, next to the reflected Gray code and the XOR codes, a 10-bit Gray code that *maximises the
minimum stripe width* ("max-min-SW"): in the reflected Gray code the finest bit plane has stripes
of width 2, which defocus blur destroys first; in a Gray code where every bit stays constant for
at least ``w`` consecutive columns, every frame is robust to blur of about ``w`` columns.
Goddyn & Gvozdjak (2003, "Binary Gray codes with long bit runs") show that a 10-bit cyclic Gray
code with minimum run length 8 exists.

A Gray code is a walk over the k-cube that flips one bit per step; its *transition sequence*
``t[0..]`` names the flipped bit.  "Every run of every bit is at least ``w`` columns long" is
exactly "any ``w`` consecutive transitions are distinct bits" (its *min gap*).

Construction for k = 10 = 2m (`product_walk`; cyclic, deterministic, no search beyond m bits):
the k-cube contains the directed torus C_L x C_L (L = 2**m) through two cyclic m-bit Gray codes
A (high bits) and B (low bits): a step either advances the A index (flips bit a_i) or the B
index.  In a Hamiltonian cycle of the directed torus the move depends only on (i + j) mod L
(if (i, j) moves along A, so must (i+1, j-1), or both would enter (i+1, j)), so the move
sequence is a pattern of L moves repeated L times, and it is Hamiltonian iff the pattern has an
odd number alpha of A moves (then beta = L - alpha is odd too).  We take alpha = L/2 + 1,
beta = L/2 - 1, spread as evenly as possible: B moves are never adjacent, so a bit of B flips
again no sooner than 2 g_B steps later; exactly two A moves per period are adjacent, so a bit of
A flips again no sooner than 2 g_A - 1 steps later (every A index meets an adjacent pair, since
alpha is odd).  With m = 5 the best cyclic 5-bit Gray code has min gap 4 (found by the exhaustive
search `cyclic_gray_walk`; 5 is impossible), so the 10-bit code has cyclic min gap
min(2*4, 2*4 - 1) = **7** -- one short of Goddyn & Gvozdjak's optimum 8, which needs their
recursive construction; the product cannot reach 8 (a gap-4 pair of A always meets an AA pair).
The narrowest stripe of every frame is then >= 7 columns (reflected Gray, XOR-04, XOR-02: 2).

For other k (the product gives only 2 g - 1 = 3 for k = 6, 8) a randomised Posa-rotation search (numba, `_search_walk`) is used instead; it reaches
min run 4 for k = 10.  Every walk is verified (every k-bit word exactly once, one bit per step,
runs >= the reported width), so a returned code is correct whatever the construction did.  The
boundary runs (the first and last stripe of each plane, clipped by the projector edge) are not
counted in `verify_walk`; `cyclic_min_gap` counts the wrap-around too.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from edge.codes import Code, int_to_digits

#: Highest min run the odd-k rotation search tries first (Goddyn & Gvozdjak's optimum for k = 10 is 8).
DEFAULT_MIN_RUN = 8


@njit(cache=True)
def _window_ok(t: np.ndarray, lo: int, hi: int, w: int) -> bool:
    """True if no bit repeats within distance < w among transitions t[lo..hi] (inclusive)."""
    for p in range(lo, hi + 1):
        for q in range(p + 1, min(hi, p + w - 1) + 1):
            if t[p] == t[q]:
                return False
    return True


@njit(cache=True)
def _reverse(a: np.ndarray, lo: int, hi: int) -> None:
    """Reverse a[lo..hi] (inclusive) in place."""
    while lo < hi:
        x = a[lo]
        a[lo] = a[hi]
        a[hi] = x
        lo += 1
        hi -= 1


@njit(cache=True)
def _search_walk(k: int, w: int, seed: int, max_steps: int) -> np.ndarray:
    """Randomised Posa-rotation search for a Hamiltonian path of the k-cube whose transitions are
    distinct over every window of ``w`` consecutive steps.

    Extend the path at its end with an allowed bit to an unvisited vertex when possible; otherwise
    rotate: if the end is adjacent (bit b) to path[i], the path path[0..i], end, path[L-2..i+1] is
    also a walk; reversing a segment keeps its windows distinct, so only the windows around the
    new junction need checking.  Returns the (2**k,) int64 vertex sequence, or an empty array
    after ``max_steps`` moves.
    """
    np.random.seed(seed)
    size = 1 << k
    pos = np.full(size, -1, dtype=np.int64)
    path = np.empty(size, dtype=np.int64)
    t = np.empty(size, dtype=np.int64)  # t[i]: bit flipped between path[i] and path[i+1]
    path[0] = np.random.randint(0, size)
    pos[path[0]] = 0
    length = 1
    opts = np.empty(k, dtype=np.int64)
    for _ in range(max_steps):
        if length == size:
            return path
        end = path[length - 1]
        cnt = 0
        for b in range(k):
            u = end ^ (1 << b)
            if pos[u] >= 0:
                continue
            ok = True
            for s in range(max(0, length - w), length - 1):
                if t[s] == b:
                    ok = False
                    break
            if ok:
                opts[cnt] = b
                cnt += 1
        if cnt > 0:
            b = opts[np.random.randint(0, cnt)]
            u = end ^ (1 << b)
            t[length - 1] = b
            path[length] = u
            pos[u] = length
            length += 1
            continue
        # rotation at the end; occasionally reverse the whole path to work on the other end
        if np.random.random() < 0.05:
            for a in range(length // 2):
                x = path[a]
                path[a] = path[length - 1 - a]
                path[length - 1 - a] = x
            for a in range((length - 1) // 2):
                x = t[a]
                t[a] = t[length - 2 - a]
                t[length - 2 - a] = x
            for a in range(length):
                pos[path[a]] = a
            continue
        b = np.random.randint(0, k)
        u = end ^ (1 << b)
        i = pos[u]
        if i < 0 or i >= length - 2:
            continue
        # candidate transitions: t[0..i-1], b, reversed(t[i+1..length-2])
        lo = max(0, i - w + 1)
        hi = min(length - 2, i + w - 1)
        tmp = np.empty(hi - lo + 1, dtype=np.int64)
        for p in range(lo, hi + 1):
            if p < i:
                tmp[p - lo] = t[p]
            elif p == i:
                tmp[p - lo] = b
            else:
                tmp[p - lo] = t[length - 2 - (p - i - 1)]
        if not _window_ok(tmp, 0, hi - lo, w):
            continue
        # apply: reverse path[i+1..length-1] and t[i+1..length-2], set t[i] = b
        _reverse(path, i + 1, length - 1)
        _reverse(t, i + 1, length - 2)
        t[i] = b
        for a in range(i + 1, length):
            pos[path[a]] = a
    return np.empty(0, dtype=np.int64)


def verify_walk(walk: np.ndarray, k: int) -> int:
    """Check a Gray walk and return its minimum interior run length.

    walk: (2**k,) int vertex sequence.  Raises ValueError unless every k-bit word occurs once and
    neighbours differ in exactly one bit.  The interior run length of a bit is the number of
    columns between two consecutive flips of it; the first and last runs (clipped by the edge of
    the projector) are not counted.
    """
    walk = np.asarray(walk, dtype=np.int64)
    if walk.shape != (2**k,) or np.unique(walk).size != 2**k or walk.min() < 0 or walk.max() >= 2**k:
        raise ValueError(f"a {k}-bit Gray walk must visit all {2**k} words once, got shape {walk.shape}")
    diff = walk[1:] ^ walk[:-1]
    if np.any(np.bitwise_count(diff.astype(np.uint64)) != 1):
        raise ValueError("consecutive words of a Gray walk must differ in exactly one bit")
    flip_bit = np.log2(diff).astype(np.int64)
    best = 2**k
    for b in range(k):
        at = np.nonzero(flip_bit == b)[0]
        if at.size >= 2:
            best = min(best, int(np.diff(at).min()))
    return best


def stripe_widths(code: Code) -> np.ndarray:
    """(n,) int: narrowest interior stripe (run of equal symbols between two changes) per frame."""
    cb = code.codebook
    out = np.empty(cb.shape[1], dtype=np.int64)
    for i in range(cb.shape[1]):
        change = np.nonzero(cb[1:, i] != cb[:-1, i])[0]
        out[i] = int(np.diff(change).min()) if change.size >= 2 else cb.shape[0]
    return out


def cyclic_gray_walk(k: int, gap: int) -> np.ndarray | None:
    """Exhaustive depth-first search (lexicographic, deterministic) for a cyclic k-bit Gray walk
    starting at 0 whose cyclic min gap is >= ``gap``; (2**k,) int64 or None if none exists.

    Only for small k (<= 5: 32 vertices, milliseconds); the wrap-around windows are checked at
    the end.
    """
    if not 1 <= k <= 5:
        raise ValueError(f"cyclic_gray_walk is an exhaustive search for 1 <= k <= 5 bits, got k={k}")
    n = 1 << k
    path = [0]
    seen = {0}
    trans: list[int] = []
    choice = [0]  # next bit to try at each depth
    while choice:
        if len(path) == n:
            d = path[-1] ^ path[0]
            if d and d & (d - 1) == 0:
                walk = np.array(path, dtype=np.int64)
                if cyclic_min_gap(walk, k) >= gap:
                    return walk
        b = choice[-1]
        advanced = False
        while b < k and len(path) < n:
            u = path[-1] ^ (1 << b)
            if u not in seen and b not in trans[max(0, len(trans) - gap + 1):]:
                choice[-1] = b + 1
                path.append(u)
                seen.add(u)
                trans.append(b)
                choice.append(0)
                advanced = True
                break
            b += 1
        if not advanced:
            choice.pop()
            if trans:
                trans.pop()
                seen.discard(path.pop())
    return None


def cyclic_min_gap(walk: np.ndarray, k: int) -> int:
    """Smallest distance between two flips of the same bit, counting the wrap-around step.

    walk: (2**k,) vertex sequence of a cyclic Gray walk (first and last word differ in one bit).
    Raises ValueError if it is not one.
    """
    walk = np.asarray(walk, dtype=np.int64)
    verify_walk(walk, k)
    d = int(walk[0] ^ walk[-1])
    if d == 0 or d & (d - 1):
        raise ValueError("the first and last word of a cyclic Gray walk must differ in exactly one bit")
    diff = np.concatenate([walk[1:] ^ walk[:-1], [d]])
    bits = np.log2(diff).astype(np.int64)
    n = walk.size
    best = n
    for b in range(k):
        at = np.nonzero(bits == b)[0]
        if at.size:
            best = min(best, int(np.diff(np.concatenate([at, [at[0] + n]])).min()))
    return best


def product_walk(high: np.ndarray, low: np.ndarray) -> np.ndarray:
    """Cyclic 2m-bit Gray walk from two cyclic m-bit walks (see the module docstring).

    high, low: (L,) cyclic Gray walks, L = 2**m.  Returns (L*L,) int64: ``high[i] << m | low[j]``
    along the directed-torus Hamiltonian cycle whose period-L move pattern is
    ``("A" + "BA" * h) * 2 + "BA"`` (h = (L/2 - 2) / 2; L/2 + 1 A moves, L/2 - 1 B moves).
    """
    high = np.asarray(high, dtype=np.int64)
    low = np.asarray(low, dtype=np.int64)
    L = high.size
    m = L.bit_length() - 1
    if L < 4 or L != 1 << m or low.size != L:
        raise ValueError(f"product_walk needs two cyclic walks of the same length 2**m >= 4, got {high.size}, {low.size}")
    h = (L // 2 - 2) // 2
    pattern = ("A" + "BA" * h) * 2 + "BA"
    assert len(pattern) == L and pattern.count("A") == L // 2 + 1
    walk = np.empty(L * L, dtype=np.int64)
    i = j = 0
    for s in range(L * L):
        walk[s] = (high[i] << m) | low[j]
        if pattern[s % L] == "A":
            i = (i + 1) % L
        else:
            j = (j + 1) % L
    return walk


@functools.lru_cache(maxsize=8)
def maxminsw_code(k: int = 10, min_run: int | None = None, *, seed: int = 1, tries: int = 3,
                  steps: int = 100_000) -> Code:
    """A k-bit Gray code whose stripes are as wide as the construction reaches.

    Returns an `edge.codes.Code` of family ``"maxminsw"`` (d_min 1; column j sends the k bits of
    the j-th word of the walk, MSB first; identity generator with messages = the walk, so every
    decoder handles it).  k = 10: the cyclic directed-torus product of two 5-bit codes (cyclic
    min gap 7, see the module docstring); ``min_run`` larger than 7 raises ValueError.  Other k
    (where the product is no better than 2 g - 1 <= 3): the randomised rotation search, trying
    ``min_run`` (or 8 and lower values) with ``tries`` seeds of ``steps`` moves each.
    """
    if not isinstance(k, (int, np.integer)) or not 2 <= k <= 12:
        raise ValueError(f"max-min-SW Gray code needs 2 <= k <= 12 bits, got k={k!r}")
    if min_run is not None and not 1 <= min_run <= k:
        raise ValueError(f"minimum run length must be in 1..k={k}, got {min_run}")
    if k == 10:
        m = k // 2
        half = None
        for g in range(m, 0, -1):
            half = cyclic_gray_walk(m, g)
            if half is not None:
                break
        assert half is not None
        walk = product_walk(half, half)
        got = cyclic_min_gap(walk, k)
        if min_run is not None and got < min_run:
            raise ValueError(f"the {k}-bit product construction reaches min run {got}, not the requested {min_run}")
        how = f"cyclic directed-torus product of two {m}-bit cyclic Gray codes of min gap {cyclic_min_gap(half, m)}"
    else:
        targets = [min_run] if min_run is not None else list(range(min(DEFAULT_MIN_RUN, k), 0, -1))
        walk = np.empty(0, dtype=np.int64)
        for w in targets:
            for t in range(tries):
                walk = _search_walk(k, w, seed + t, steps)
                if walk.size:
                    break
            if walk.size:
                break
        if not walk.size:
            raise ValueError(f"no {k}-bit Gray code with interior runs >= {targets[-1]} found in {tries} restarts")
        got = verify_walk(walk, k)
        how = "rotation search, interior runs"
    g = np.eye(k, dtype=np.uint8)
    codebook = int_to_digits(walk, k)
    return Code(
        name=f"maxminsw-{k}", family="maxminsw", codebook=codebook, k=k, systematic=True,
        generator=g, messages=walk, order="custom", promised_d_min=1,
        construction=f"Gray walk of the {k}-cube with every bit run >= {got} columns ({how})",
    )

"""Codes found by search for any (n, k), deterministic given a seed.

Two constructions:

* ``method="linear"`` (default): local search over systematic generators ``[I_k | P]``.  Each of
  the n-k parity columns is a k-bit integer; a move replaces one column by a random one and is
  kept when it does not worsen the objective (d_min, then fewer codewords of weight d_min).  The
  weight of every message is updated in O(2**k) per move, so tens of thousands of moves take
  about a second.  Restarts from random generators; the best code over all restarts wins.
* ``method="poisson"``: high-dimensional Poisson-disk sampling (dart throwing) in {0,1}**n: random
  words are accepted when they lie at Hamming distance >= r from every accepted word; r is raised
  while 2**k words still fit within the dart budget.  The result is non-linear (no generator).

The paper's (31, 10, 12) is reached by the shortened extended BCH (32, 11, 12); `search_code`
finds what a seeded search reaches (compare with ``tools/bench_code_search.py``).
"""

from __future__ import annotations

import functools

import numpy as np

from .code import Code, int_to_digits
from .linear import from_generator

MAX_K_SEARCH = 16


def _parity(x: np.ndarray) -> np.ndarray:
    return (np.bitwise_count(x) & 1).astype(np.int32)


def _objective(weights: np.ndarray) -> tuple[int, int]:
    nz = weights[1:]
    d = int(nz.min())
    return d, -int((nz == d).sum())


def _check(n: int, k: int) -> None:
    if not (isinstance(n, (int, np.integer)) and isinstance(k, (int, np.integer))):
        raise ValueError(f"search needs integer n, k; got n={n!r}, k={k!r}")
    if not 1 <= k <= MAX_K_SEARCH:
        raise ValueError(f"search needs 1 <= k <= {MAX_K_SEARCH} (exhaustive d_min), got k={k}")
    if not k < n <= 255:
        raise ValueError(f"search needs k < n <= 255, got (n, k) = ({n}, {k})")


def search_parity_columns(n: int, k: int, *, seed: int = 0, iterations: int = 20000,
                          restarts: int = 4) -> tuple[np.ndarray, int]:
    """Local search for a good [n, k] binary linear code.

    Returns (columns, d_min): columns is (n-k,) int64, the parity columns of ``[I_k | P]`` as k-bit
    integers (bit k-1-i = row i), and d_min is the exact minimum distance of that code.
    """
    _check(n, k)
    rng = np.random.default_rng(seed)
    m = np.arange(1 << k, dtype=np.int64)
    base_weight = np.bitwise_count(m).astype(np.int32)
    r = n - k
    best_cols, best_obj = None, (-1, 0)
    per_restart = max(1, iterations // max(1, restarts))
    for _ in range(max(1, restarts)):
        cols = rng.integers(1, 1 << k, size=r)
        bits = np.stack([_parity(m & c) for c in cols])  # (r, 2**k)
        weights = base_weight + bits.sum(axis=0, dtype=np.int32)
        obj = _objective(weights)
        for _ in range(per_restart):
            j = int(rng.integers(r))
            c = int(rng.integers(1, 1 << k))
            new_bits = _parity(m & c)
            trial = weights - bits[j] + new_bits
            t_obj = _objective(trial)
            if t_obj >= obj:
                weights, obj = trial, t_obj
                bits[j] = new_bits
                cols[j] = c
        if obj > best_obj:
            best_obj, best_cols = obj, cols.copy()
    return np.asarray(best_cols, dtype=np.int64), best_obj[0]


@functools.lru_cache(maxsize=32)
def search_code(n: int, k: int, *, seed: int = 0, iterations: int = 20000, restarts: int = 4,
                method: str = "linear", order: str = "gray") -> Code:
    """A code of length n for 2**k columns found by seeded search (see module docstring)."""
    _check(n, k)
    if method == "linear":
        cols, d = search_parity_columns(n, k, seed=seed, iterations=iterations, restarts=restarts)
        parity = int_to_digits(cols, k).T  # (k, n-k), row i = bit i (MSB first) of each column
        g = np.concatenate([np.eye(k, dtype=np.uint8), parity], axis=1)
        return from_generator(
            g, name=f"search-{n}-{k}", family="search",
            construction=f"local search over systematic generators (seed {seed}, {iterations} moves, "
                         f"{restarts} restarts)", order=order, promised_d_min=d,
        )
    if method == "poisson":
        if k > 13:
            raise ValueError(f"Poisson-disk search stores a non-linear code: needs k <= 13, got k={k}")
        if n > 64:
            raise ValueError(f"Poisson-disk search packs words in 64 bits: needs n <= 64, got n={n}")
        words, r = poisson_disk_words(n, k, seed=seed, darts=iterations * 50)
        return Code(
            name=f"poisson-{n}-{k}", family="search", codebook=int_to_digits(words, n), k=k,
            construction=f"Poisson-disk sampling in {{0,1}}^{n} with radius {r} (seed {seed})",
            order="custom", promised_d_min=r,
        )
    raise ValueError(f"search method must be 'linear' or 'poisson', got {method!r}")


def poisson_disk_words(n: int, k: int, *, seed: int = 0, darts: int = 1_000_000) -> tuple[np.ndarray, int]:
    """2**k words of n bits (as int64) with pairwise distance >= r, for the largest r reached.

    Dart throwing with a fixed budget per radius; radius 1 always succeeds (distinct words).
    """
    target = 1 << k
    best = None
    radius = 1
    while True:
        rng = np.random.default_rng(seed + radius)
        accepted = np.zeros(target, dtype=np.uint64)
        count = 0
        thrown = 0
        batch = 256
        while count < target and thrown < darts:
            cand = rng.integers(0, 1 << n, size=batch, dtype=np.uint64) if n < 64 else \
                rng.integers(0, np.iinfo(np.int64).max, size=batch).astype(np.uint64)
            thrown += batch
            for w in cand:
                if count and np.bitwise_count(accepted[:count] ^ w).min() < radius:
                    continue
                accepted[count] = w
                count += 1
                if count == target:
                    break
        if count < target:
            break
        best = (accepted.astype(np.int64), radius)
        radius += 1
        if radius > n:
            break
    assert best is not None
    order = np.argsort(best[0])
    return best[0][order], best[1]


__all__ = ["search_code", "search_parity_columns", "poisson_disk_words"]

"""Codes found by search for any (n, k), deterministic given a seed.

Three constructions, and a default that takes the better of two:

* ``method="linear"``: tabu search over the n generator columns of a binary linear code.  A
  code is a multiset of n nonzero k-bit columns c_0..c_{n-1}; codeword m has weight
  ``w(m) = sum_i parity(m & c_i)``.  One move replaces one column by the best other k-bit value
  (every one of the 2**k - 1 candidates is scored at once by a Walsh-Hadamard transform of the
  per-message penalty change, O(k 2**k)); the column just changed is tabu for a few moves, so
  the search walks on through worsening moves.  The objective is lexicographic, (d_min, fewer
  codewords of weight d_min): the energy ``sum_m max(0, T - w(m))**2`` with the target
  ``T = d_best + 1`` is the number of weight-d_best words when no word is lighter; when it
  reaches 0 the target is raised.  Restarts from random columns; stops early at the Griesmer
  bound.  The result is put into systematic form ``[I_k | P]`` (frames permuted if needed).
* ``method="cyclic"``: exhaustive search over cyclic codes.  For every odd length N <= 63 with
  N = n + s (then shortened by s) or N = n - 1 (then extended by an overall parity bit), every
  divisor g(x) of x**N - 1 of degree N - (k + s) is a cyclic code; its d_min (after shortening
  or extension) is computed exhaustively and the best is kept (no randomness).
* ``method="poisson"``: high-dimensional Poisson-disk sampling (dart throwing) in {0,1}**n: random
  words are accepted when they lie at Hamming distance >= r from every accepted word; r is raised
  while 2**k words still fit within the dart budget.  The result is non-linear (no generator).
* ``method="best"`` (default, used by the registry names ``search-N-K``): the cyclic search, and
  the tabu search unless the cyclic code already meets the Griesmer bound; the better code wins.

For (31, 10) the tabu search reaches d_min 10 (11 for some seeds), the cyclic search 12 (the
even-weight subcode of the BCH (31, 11, 11) code), like the shortened extended BCH (32, 11, 12)
of ``ecc-31-10``; for (22, 10) both reach 8 (best known).  See ``tools/bench_code_search.py``.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from .code import Code, digits_to_int, int_to_digits
from .gfq import poly2_mul
from .linear import from_generator
from .table import griesmer_bound
from .words import pack_words

MAX_K_SEARCH = 16
MAX_N_CYCLIC = 63
METHODS = ("best", "linear", "cyclic", "poisson")


# ---------------------------------------------------------------------------------------------
# numba kernels


@njit(cache=True)
def _popcount(x: int) -> int:
    c = 0
    while x:
        x &= x - 1
        c += 1
    return c


@njit(cache=True)
def _popcount64(x: np.uint64) -> int:
    c = 0
    while x:
        x &= x - np.uint64(1)
        c += 1
    return c


@njit(cache=True)
def _next_random(state: np.ndarray) -> np.uint64:
    """xorshift64* step on state[0] (uint64): the same stream on every platform."""
    x = state[0]
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    state[0] = x
    return x * np.uint64(2685821657736338717)


@njit(cache=True)
def _walsh_hadamard(a: np.ndarray) -> None:
    """In-place unnormalised Walsh-Hadamard transform of a (2**k,) int64 array."""
    size = a.size
    h = 1
    while h < size:
        for s in range(0, size, 2 * h):
            for t in range(s, s + h):
                x = a[t]
                y = a[t + h]
                a[t] = x + y
                a[t + h] = x - y
        h *= 2


@njit(cache=True)
def _set_penalty(pen: np.ndarray, target: int) -> None:
    for w in range(pen.size):
        pen[w] = (target - w) ** 2 if w < target else 0


@njit(cache=True)
def _min_weight_and_count(weights: np.ndarray) -> tuple[int, int]:
    d = np.int64(1) << 40
    count = 0
    for m in range(1, weights.size):
        if weights[m] < d:
            d = weights[m]
            count = 1
        elif weights[m] == d:
            count += 1
    return d, count


@njit(cache=True)
def _tabu_columns(cols: np.ndarray, k: int, steps: int, d_stop: int, tenure: int,
                  seed: int) -> tuple[np.ndarray, int, int, int]:
    """Tabu search from the n columns ``cols`` (int64 k-bit values, modified in place).

    Returns (best_cols, d_min, number of weight-d_min codewords, moves made).
    """
    n = cols.size
    size = 1 << k
    weights = np.zeros(size, np.int64)
    for j in range(n):
        for m in range(size):
            weights[m] += _popcount(m & cols[j]) & 1
    best_cols = cols.copy()
    best_d, best_count = _min_weight_and_count(weights)
    if best_d >= d_stop:
        return best_cols, best_d, best_count, 0
    target = best_d + 1
    pen = np.zeros(n + 2, np.int64)
    _set_penalty(pen, target)
    energy = 0
    for m in range(1, size):
        energy += pen[weights[m]]
    best_energy = energy
    state = np.zeros(1, np.uint64)
    state[0] = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(0x2545F4914F6CDD1D)
    delta = np.zeros(size, np.int64)
    tabu_until = np.zeros(n, np.int64)
    for step in range(1, steps + 1):
        j = np.int64(_next_random(state) >> np.uint64(33)) % n
        while tabu_until[j] >= step:
            j = np.int64(_next_random(state) >> np.uint64(33)) % n
        old = cols[j]
        # energy with column j removed, and the penalty change of each message if it is put back
        base = 0
        total = 0
        delta[0] = 0
        for m in range(1, size):
            w = weights[m] - (_popcount(m & old) & 1)
            delta[m] = pen[w + 1] - pen[w]
            total += delta[m]
            base += pen[w]
        _walsh_hadamard(delta)  # sum_m parity(m & c) delta[m] = (total - delta[c]) / 2
        best_value = np.int64(1) << 62
        choice = -1
        ties = 0
        for c in range(1, size):
            if c == old:
                continue
            value = total - delta[c]
            if value < best_value:
                best_value = value
                choice = c
                ties = 1
            elif value == best_value:
                ties += 1
                if np.int64(_next_random(state) >> np.uint64(33)) % ties == 0:
                    choice = c
        for m in range(1, size):
            weights[m] += (_popcount(m & choice) & 1) - (_popcount(m & old) & 1)
        cols[j] = choice
        tabu_until[j] = step + tenure
        energy = base + best_value // 2
        if energy < best_energy:
            best_energy = energy
            d, count = _min_weight_and_count(weights)
            if d > best_d or (d == best_d and count < best_count):
                best_d, best_count = d, count
                best_cols[:] = cols
            if d >= d_stop:
                return best_cols, best_d, best_count, step
            if d >= target:  # target reached: aim one higher
                target = d + 1
                _set_penalty(pen, target)
                energy = 0
                for m in range(1, size):
                    energy += pen[weights[m]]
                best_energy = energy
    return best_cols, best_d, best_count, steps


@njit(cache=True)
def _weight_profile(rows: np.ndarray) -> tuple[int, int]:
    """(d_min, number of weight-d_min words) of the binary code spanned by ``rows``.

    rows: (k,) uint64, each an n-bit codeword (n <= 64).  All 2**k - 1 nonzero codewords are
    visited in Gray-code order, one row XOR per step.
    """
    k = rows.size
    word = np.uint64(0)
    d = 65
    count = 0
    for i in range(1, 1 << k):
        low = 0
        while not (i >> low) & 1:
            low += 1
        word ^= rows[low]
        w = _popcount64(word)
        if w < d:
            d = w
            count = 1
        elif w == d:
            count += 1
    return d, count


# ---------------------------------------------------------------------------------------------
# tabu search over generator columns


def _check(n: int, k: int) -> None:
    if not (isinstance(n, (int, np.integer)) and isinstance(k, (int, np.integer))):
        raise ValueError(f"search needs integer n, k; got n={n!r}, k={k!r}")
    if not 1 <= k <= MAX_K_SEARCH:
        raise ValueError(f"search needs 1 <= k <= {MAX_K_SEARCH} (exhaustive d_min), got k={k}")
    if not k < n <= 255:
        raise ValueError(f"search needs k < n <= 255, got (n, k) = ({n}, {k})")


def _columns_to_generator(cols: np.ndarray, k: int) -> np.ndarray:
    """(n,) k-bit column integers -> (k, n) uint8 generator; row i = bit k-1-i of each column."""
    return int_to_digits(np.asarray(cols, dtype=np.int64), k).T.copy()


def search_generator_columns(n: int, k: int, *, seed: int = 0, iterations: int = 20000,
                             restarts: int = 4) -> tuple[np.ndarray, int, int]:
    """Tabu search for a good [n, k] binary linear code (see the module docstring).

    Returns (columns, d_min, count): columns is (n,) int64, the generator columns as k-bit
    integers (bit k-1-i = row i); d_min its minimum distance and count the number of codewords
    of weight d_min.  ``iterations`` moves in all, split over ``restarts`` random starts; the
    search stops as soon as d_min meets the Griesmer bound.  Deterministic given the seed.
    """
    _check(n, k)
    if iterations < 1 or restarts < 1:
        raise ValueError(f"search needs iterations >= 1 and restarts >= 1, got {iterations}, {restarts}")
    rng = np.random.default_rng(seed)
    d_stop = griesmer_bound(n, k)
    tenure = max(1, min(7, n // 3))
    per_restart = max(1, iterations // restarts)
    best: tuple[int, int] = (-1, 0)
    best_cols = None
    for restart in range(restarts):
        cols = rng.integers(1, 1 << k, size=n).astype(np.int64)
        found, d, count, _ = _tabu_columns(cols, k, per_restart, d_stop, tenure,
                                           int(seed) * 1000003 + restart)
        if (d, -count) > best:
            best, best_cols = (d, -count), found.copy()
        if d >= d_stop:
            break
    assert best_cols is not None
    return best_cols, best[0], -best[1]


def search_parity_columns(n: int, k: int, *, seed: int = 0, iterations: int = 20000,
                          restarts: int = 4) -> tuple[np.ndarray, int]:
    """`search_generator_columns` in systematic form.

    Returns (columns, d_min): columns is (n-k,) int64, the parity columns of ``[I_k | P]`` as k-bit
    integers (bit k-1-i = row i) of the code found (frames permuted first where the first k
    columns are not an information set).
    """
    cols, d, _ = search_generator_columns(n, k, seed=seed, iterations=iterations, restarts=restarts)
    from .gf2 import systematic_form
    from .linear import information_set_first

    g = systematic_form(information_set_first(_columns_to_generator(cols, k)))
    return digits_to_int(g[:, k:].T), d


# ---------------------------------------------------------------------------------------------
# exhaustive search over cyclic codes (shortened or extended)




@functools.lru_cache(maxsize=64)
def _cyclotomic_factors(length: int) -> tuple[int, ...]:
    """Irreducible binary factors of x**length - 1 (odd length), as integers (bit i = x**i)."""
    import galois

    factors, _ = galois.Poly.Degrees([length, 0]).factors()
    return tuple(sorted(int(f) for f in factors))


def _divisors_of_degree(factors: tuple[int, ...], degree: int, limit: int) -> list[int]:
    """Products of distinct factors with total degree ``degree`` (at most ``limit``, in a fixed order)."""
    out: list[int] = []
    degs = [f.bit_length() - 1 for f in factors]

    def walk(i: int, poly: int, left: int) -> None:
        if len(out) >= limit:
            return
        if left == 0:
            out.append(poly)
            return
        if i == len(factors) or left < 0:
            return
        walk(i + 1, poly2_mul(poly, factors[i]), left - degs[i])
        walk(i + 1, poly, left)

    walk(0, 1, degree)
    return out


def search_cyclic(n: int, k: int, *, max_candidates: int = 4096) -> tuple[np.ndarray, int, int, str] | None:
    """Best binary [n, k] code among shortened and extended cyclic codes (exhaustive, no seed).

    Candidates: cyclic codes of odd length N = n + s <= 63 and dimension k + s (k + s <= 16),
    shortened by s, and of length N = n - 1 and dimension k, extended by an overall parity bit;
    at most ``max_candidates`` generator polynomials per (N, s).  Returns (generator (k, n)
    uint8 systematic, d_min, count of weight-d_min words, description), or None when no
    candidate exists for this (n, k).
    """
    _check(n, k)
    from .gf2 import cyclic_generator, systematic_form

    best = None
    plans = [(n + s, s, False) for s in range(0, MAX_K_SEARCH - k + 1)] + [(n - 1, 0, True)]
    for length, s, extend in plans:
        if length % 2 == 0 or length > MAX_N_CYCLIC or length <= k + s:
            continue
        for poly in _divisors_of_degree(_cyclotomic_factors(length), length - (k + s), max_candidates):
            g = systematic_form(cyclic_generator(poly, length))[s:, s:]
            if extend:
                g = np.concatenate([g, g.sum(axis=1, keepdims=True) & 1], axis=1).astype(np.uint8)
            d, count = _weight_profile(pack_words(g))
            if best is None or (d, -count) > (best[1], -best[2]):
                what = "extended by parity" if extend else (f"shortened by {s}" if s else "")
                desc = f"cyclic ({length}, {k + s}) code g(x)=0x{poly:x}" + (f", {what}" if what else "")
                best = (g, int(d), int(count), desc)
    return best


# ---------------------------------------------------------------------------------------------
# the Code


@functools.lru_cache(maxsize=32)
def search_code(n: int, k: int, *, seed: int = 0, iterations: int = 20000, restarts: int = 4,
                method: str = "best", order: str = "gray") -> Code:
    """A code of length n for 2**k columns found by search (see the module docstring).

    The returned `Code` computes its d_min exhaustively; the search's own d_min is checked
    against it (``promised_d_min``).
    """
    _check(n, k)
    if method not in METHODS:
        raise ValueError(f"search method must be one of {', '.join(METHODS)}; got {method!r}")
    name = f"search-{n}-{k}"
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
    candidates: list[tuple[int, int, np.ndarray, str]] = []
    if method in ("cyclic", "best"):
        found = search_cyclic(n, k) if n <= MAX_N_CYCLIC + 1 else None
        if found is not None:
            g, d, count, desc = found
            candidates.append((d, -count, g, f"exhaustive search over cyclic codes: {desc}"))
        elif method == "cyclic":
            raise ValueError(f"no cyclic code of odd length <= {MAX_N_CYCLIC} shortens or extends to ({n}, {k})")
    reached_bound = bool(candidates) and candidates[0][0] >= griesmer_bound(n, k)
    if method == "linear" or (method == "best" and not reached_bound):
        cols, d, count = search_generator_columns(n, k, seed=seed, iterations=iterations, restarts=restarts)
        candidates.append((d, -count, _columns_to_generator(cols, k),
                           f"tabu search over generator columns (seed {seed}, {iterations} moves, "
                           f"{restarts} restarts)"))
    d, _, g, construction = max(candidates, key=lambda c: (c[0], c[1]))
    return from_generator(g, name=name, family="search", construction=construction, order=order,
                          promised_d_min=d)


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


__all__ = ["search_code", "search_generator_columns", "search_parity_columns", "search_cyclic",
           "poisson_disk_words", "METHODS"]

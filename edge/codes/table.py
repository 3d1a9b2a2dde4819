"""The code lookup table: the best code this library builds for every (n, k), next to the bounds.

Codes are handled as column sets while the table is built: an [n, k] binary linear code is a list
of n generator columns, each a k-bit integer (bit k-1-i = generator row i), and the weight of
message m is ``sum_j parity(m & c_j)``.  Candidates for a cell (n, k):

1. family codes (Hamming, extended Hamming, Golay, Reed-Muller, BCH and extended BCH of length
   7..128) shortened to k (systematic shortening: messages whose first K-k bits are 0);
2. puncturing the best (n+1, k) code at the column whose removal keeps d_min highest;
3. adding to the best (n-1, k) code the column that maximises d_min (all 2**k candidates);
4. juxtaposition [G1 | G2] of the best (n1, k) and (n-n1, k) codes (d >= d1 + d2).

d_min of every candidate is exact (all 2**k messages).  Ties prefer family codes (in the order
of `FAMILY_PREFERENCE`), then fewer minimum-weight codewords.  `best(n, k)` turns a cell into a
`Code` (systematic generator, Gray column order over a minimum-weight basis).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from math import comb

import numpy as np

from .code import Code, digits_to_int, int_to_digits
from .families import bch_table, bch_generator, hamming_generator, reed_muller_generator
from .gf2 import cyclic_generator, systematic_form
from .linear import GOLAY_23_POLY, from_generator, information_set_first

MAX_K_TABLE = 12
MAX_N_TABLE = 128
TABLE_K = range(6, 13)
TABLE_N_MAX = 63

#: Published best-known minimum distances for k = 10 (Brouwer/Grassl tables), (lower, upper).
KNOWN_K10 = {15: (4, 4), 19: (5, 5), 20: (6, 6), 21: (7, 7), 22: (8, 8), 27: (9, 9), 28: (10, 10),
             31: (12, 12), 40: (16, 16), 48: (20, 20), 63: (27, 28), 64: (28, 28)}

FAMILY_PREFERENCE = ("golay", "bch", "hamming", "reed-muller", "identity")


def griesmer_bound(n: int, k: int) -> int:
    """Largest d with sum_{i<k} ceil(d / 2**i) <= n (upper bound on d_min of any [n, k] linear code)."""
    if not 1 <= k <= n:
        raise ValueError(f"Griesmer bound needs 1 <= k <= n, got (n, k) = ({n}, {k})")
    d = 0
    while sum(-(-(d + 1) // (1 << i)) for i in range(k)) <= n:
        d += 1
    return d


@dataclass(frozen=True)
class Cell:
    """Best code found for one (n, k): its generator columns and how it was made."""

    n: int
    k: int
    d_min: int
    min_weight_count: int
    family: str
    construction: str
    columns: tuple[int, ...]
    direct: bool  # a family code shortened to k, with no further surgery


@dataclass(frozen=True)
class _Base:
    family: str
    label: str
    parity_rows: np.ndarray  # (K, N-K) uint8, systematic generator [I | P]
    n: int
    k: int


def _systematic(g: np.ndarray) -> np.ndarray:
    g = np.asarray(g, dtype=np.uint8)
    try:
        return systematic_form(g)
    except ValueError:
        return systematic_form(information_set_first(g))


def _add_parity(g: np.ndarray) -> np.ndarray:
    return np.concatenate([g, (g.sum(axis=1, keepdims=True) & 1).astype(np.uint8)], axis=1)


@functools.lru_cache(maxsize=1)
def family_bases() -> tuple[_Base, ...]:
    """Systematic generators of every family code used by the table (length <= 128)."""
    out: list[_Base] = []

    def add(family: str, label: str, g: np.ndarray) -> None:
        s = _systematic(g)
        k, n = s.shape
        out.append(_Base(family, label, s[:, k:].copy(), n, k))

    g23 = cyclic_generator(GOLAY_23_POLY, 23)
    add("golay", "Golay (23,12,7)", g23)
    add("golay", "extended Golay (24,12,8)", _add_parity(g23))
    for m in range(3, 8):
        h = hamming_generator(m)
        n = (1 << m) - 1
        add("hamming", f"Hamming ({n},{n - m},3)", h)
        add("hamming", f"extended Hamming ({n + 1},{n - m},4)", _add_parity(h))
    for n in (15, 31, 63, 127):
        for k, delta, _ in bch_table(n):
            if delta <= 3 or k < 2:
                continue  # Hamming codes listed above; repetition codes below
            g = bch_generator(n, k)
            add("bch", f"BCH ({n},{k},>={delta})", g)
            add("bch", f"extended BCH ({n + 1},{k},>={delta + (delta % 2)})", _add_parity(g))
    for m in range(2, 7):
        for r in range(1, m - 1):
            k = sum(comb(m, i) for i in range(r + 1))
            add("reed-muller", f"Reed-Muller RM({r},{m}) ({1 << m},{k},{1 << (m - r)})", reed_muller_generator(r, m))
    return tuple(out)


class _Weights:
    """Parity of (m & c) for every message m of k bits; cached per k."""

    def __init__(self, k: int) -> None:
        self.k = k
        self.m = np.arange(1 << k, dtype=np.int64)
        self._table: np.ndarray | None = None

    def column(self, c: int) -> np.ndarray:
        return (np.bitwise_count(self.m & c) & 1).astype(np.int16)

    def weights(self, columns) -> np.ndarray:
        w = np.zeros(1 << self.k, dtype=np.int16)
        for c in columns:
            w += self.column(int(c))
        return w

    def all_columns(self) -> np.ndarray:
        """(2**k, 2**k) int16: parity(m & c) for all m (rows), c (columns)."""
        if self._table is None:
            self._table = (np.bitwise_count(self.m[:, None] & self.m[None, :]) & 1).astype(np.int16)
        return self._table


def _score(w: np.ndarray) -> tuple[int, int]:
    nz = w[1:]
    d = int(nz.min())
    return d, int((nz == d).sum())


def _rank_key(cell: Cell) -> tuple:
    pref = FAMILY_PREFERENCE.index(cell.family) if (cell.direct and cell.family in FAMILY_PREFERENCE) \
        else len(FAMILY_PREFERENCE)
    return (-cell.d_min, pref, cell.min_weight_count)


def _shortened_columns(base: _Base, k: int) -> tuple[int, ...]:
    """Columns of the family code shortened to k message bits (identity part included)."""
    p = base.parity_rows[base.k - k:]  # rows of the kept message bits, (k, N-K)
    parity_cols = digits_to_int(p.T)  # message-space integers, row i = bit k-1-i
    unit = [1 << (k - 1 - i) for i in range(k)]
    return tuple(unit + [int(c) for c in parity_cols if c])


@functools.lru_cache(maxsize=None)
def table_for_k(k: int, n_max: int = TABLE_N_MAX) -> dict[int, Cell]:
    """Best cell for every n in k..n_max (see module docstring)."""
    if not 1 <= k <= MAX_K_TABLE:
        raise ValueError(f"the code table searches 1 <= k <= {MAX_K_TABLE} (exhaustive d_min over 2**k words), got k={k}")
    if not k <= n_max <= MAX_N_TABLE:
        raise ValueError(f"the code table covers k <= n <= {MAX_N_TABLE}, got n={n_max}")
    ws = _Weights(k)
    cells: dict[int, Cell] = {}
    weights: dict[int, np.ndarray] = {}

    def offer(cell: Cell, w: np.ndarray) -> None:
        old = cells.get(cell.n)
        if old is None or _rank_key(cell) < _rank_key(old):
            cells[cell.n] = cell
            weights[cell.n] = w

    def make(n, w, family, construction, columns, direct=False) -> Cell:
        d, count = _score(w)
        return Cell(n, k, d, count, family, construction, tuple(int(c) for c in columns), direct)

    # trivial code and family codes
    unit = tuple(1 << (k - 1 - i) for i in range(k))
    w0 = ws.weights(unit)
    offer(make(k, w0, "identity", f"uncoded [{k},{k},1]", unit, True), w0)
    for base in family_bases():
        if base.k < k:
            continue
        cols = _shortened_columns(base, k)
        n = len(cols)
        if n > n_max or n < k:
            continue
        w = ws.weights(cols)
        how = base.label if base.k == k else f"{base.label} shortened by {base.k - k}"
        offer(make(n, w, base.family, how, cols, True), w)

    table = ws.all_columns() if k <= MAX_K_TABLE else None
    for _ in range(2):
        # upward: add the best column, juxtapose
        for n in range(k + 1, n_max + 1):
            if n - 1 in cells:
                prev, w = cells[n - 1], weights[n - 1]
                best_c = _best_choice((w[:, None] + table)[1:], exclude_first=True)
                w2 = w + table[:, best_c]
                offer(make(n, w2, prev.family if prev.family != "identity" else "greedy",
                           f"{_short(prev)} + 1 greedy column", prev.columns + (best_c,)), w2)
            for n1 in range(k, n // 2 + 1):
                n2 = n - n1
                if n1 in cells and n2 in cells:
                    w2 = weights[n1] + weights[n2]
                    a, b = cells[n1], cells[n2]
                    offer(make(n, w2, "juxtaposition", f"[{_short(a)} | {_short(b)}]",
                               a.columns + b.columns), w2)
        # downward: puncture greedily
        for n in range(n_max - 1, k - 1, -1):
            if n + 1 not in cells:
                continue
            nxt, w = cells[n + 1], weights[n + 1]
            cols = np.array(nxt.columns, dtype=np.int64)
            per_col = table[:, cols]  # (2**k, n+1)
            j = _best_choice((w[:, None] - per_col)[1:])
            if j < 0:
                continue
            w2 = w - per_col[:, j]
            offer(make(n, w2, nxt.family, f"{_short(nxt)} punctured at frame {j}",
                       tuple(np.delete(cols, j))), w2)
    return {n: cells[n] for n in sorted(cells) if n <= n_max}


def _best_choice(candidate_weights: np.ndarray, exclude_first: bool = False) -> int:
    """Column index of (nonzero messages, candidates) weights with the largest d_min, ties broken by
    fewest minimum-weight words; -1 if every candidate has d_min 0."""
    d = candidate_weights.min(axis=0).astype(np.int64)
    count = (candidate_weights == d[None, :]).sum(axis=0)
    score = d * (1 << 20) - count
    if exclude_first:
        score[0] = -(1 << 40)
    score[d <= 0] = -(1 << 40)
    j = int(np.argmax(score))
    return j if score[j] > -(1 << 40) else -1


def _short(cell: Cell) -> str:
    if cell.direct:
        return cell.construction
    return f"[{cell.n},{cell.k},{cell.d_min}]"


def best_cell(n: int, k: int) -> Cell:
    """The best cell for (n, k); ValueError for impossible or unsupported pairs."""
    _check_nk(n, k)
    return table_for_k(k, max(TABLE_N_MAX, n))[n]


def _check_nk(n: int, k: int) -> None:
    if not (isinstance(n, (int, np.integer)) and isinstance(k, (int, np.integer))):
        raise ValueError(f"(n, k) must be integers, got ({n!r}, {k!r})")
    if k < 1 or n < k:
        raise ValueError(f"no [n, k] code with n < k or k < 1: got (n, k) = ({n}, {k})")
    if k > MAX_K_TABLE:
        raise ValueError(f"best(n, k) needs k <= {MAX_K_TABLE} (exhaustive d_min over 2**k messages), got k={k}")
    if n > MAX_N_TABLE:
        raise ValueError(f"best(n, k) covers n <= {MAX_N_TABLE}, got n={n}")


@functools.lru_cache(maxsize=64)
def best(n: int, k: int, *, order: str = "gray") -> Code:
    """The best binary code this library builds for (n, k), as a `Code` named ``ecc-n-k``."""
    cell = best_cell(n, k)
    g = int_to_digits(np.array(cell.columns, dtype=np.int64), k).T  # (k, n)
    return from_generator(
        g, name=f"ecc-{n}-{k}", family=cell.family, construction=cell.construction, order=order,
        promised_d_min=cell.d_min,
    )


@dataclass(frozen=True)
class TableRow:
    n: int
    k: int
    d_min: int
    griesmer: int
    known: tuple[int, int] | None
    family: str
    construction: str


def table_rows(ks=TABLE_K, n_max: int = TABLE_N_MAX, progress: bool = False) -> list[TableRow]:
    """Rows of the lookup table for every k in ks and n in k..n_max."""
    ks = list(ks)
    iterator = ks
    if progress:
        from tqdm import tqdm

        iterator = tqdm(ks, desc="code table", unit="k")
    rows = []
    for k in iterator:
        cells = table_for_k(k, n_max)
        for n, cell in cells.items():
            rows.append(TableRow(n, k, cell.d_min, griesmer_bound(n, k),
                                 KNOWN_K10.get(n) if k == 10 else None, cell.family, cell.construction))
    return rows

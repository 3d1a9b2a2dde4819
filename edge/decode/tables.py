"""Per-code lookup tables for the numba decoders (built once per code, cached).

Binary codewords are packed into uint64 masks with bit ``i`` = frame ``i`` (n <= 64), the bit
order of `edge.codes.words.pack_words`; the kernels pack received words the same way.  An
*information set* ``I`` is a set of k positions on which the codebook takes every k-bit value
exactly once; ``col_of_info[pack_I(c)]`` maps a codeword to its column.  For linear codes the
complement ``J`` carries the syndrome and a coset-leader table gives the nearest codeword of a
hard-decision word in Hamming distance (for n - k <= `MAX_SYNDROME_BITS`).

The soft decoder enumerates differences ``D`` (nonzero codewords of a linear code) sorted by
Hamming weight and, inside a weight class, by their pattern on positions 0..5 (group 0), which
is what its branch-and-bound prunes on.

Lane-parallel search (`kernels.soft_lanes`, `kernels.hard_lean`).  For a *column-linear* code
(``masks[i ^ j] == masks[i] ^ masks[j]``: the column index is itself a message, as for every
built-in linear code) the column of ``c_ref xor D`` is ``col(c_ref) ^ col(D)``, and the hard
decision ``h`` maps to a column and syndrome by XOR of per-position contributions
(``col_bit``, ``syn_col``).  The nonzero codewords are grouped in weight classes
(``cls_weight``), each D stored as its sorted positions (``dpos``) and column (``dcol``).

Per-path table structures.  Each search kernel of `edge.decode.kernels` takes the tables of its
path as one NamedTuple of arrays (``tables``): `ScalarTables`, `LaneTables`, `ScanTables`,
`FoldTables`, `HardTables`, `NaryTables`, built once per code from `CodeTables` (its
``scalar_tables`` ... properties, cached).  The fields are the `CodeTables` attributes of the
same name.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..codes import Code
from ..codes.gf2 import as_ints, independent
from ..codes.words import bit_weights, pack_words, unpack_words

#: Largest n - k for which a full coset-leader table (2**(n-k) entries) is built.
MAX_SYNDROME_BITS = 20
#: Bits per lookup-table group in the cost kernels (tables of 2**GROUP_BITS entries).
GROUP_BITS = 6
#: Column bits of a Walsh-Hadamard block / of a fold row in `kernels.soft_band_fold` (measured
#: with tools/bench_decode.py's input, ecc-22-10 and a 128-column band: blocks of 32 / 64 / 128
#: columns 82 / 77 / 82 ms single-threaded; 1-3 row bits within 1 ms of each other).
FOLD_BLOCK_BITS = 6
FOLD_LANE_BITS = 2


class ScalarTables(NamedTuple):
    """`kernels.soft_binary`: packed codewords, information-set and syndrome packing, coset
    leaders, the nonzero codewords by weight class and group-0 sublist (see `CodeTables`)."""

    masks: np.ndarray
    comp_info: np.ndarray
    col_of_info: np.ndarray
    comp_syn: np.ndarray
    leader: np.ndarray
    has_leader: bool
    linear: bool
    diff_masks: np.ndarray
    diff_info: np.ndarray
    class_start: np.ndarray
    sub_start: np.ndarray
    sub_p0: np.ndarray
    class_sub: np.ndarray


class LaneTables(NamedTuple):
    """`kernels.soft_lanes`: per-position syndrome / column contributions, coset leaders and
    their columns, the nonzero codewords by weight class as positions and columns."""

    masks: np.ndarray
    syn_col: np.ndarray
    col_bit: np.ndarray
    leader: np.ndarray
    leader_col: np.ndarray
    has_leader: bool
    cls_weight: np.ndarray
    cls_start: np.ndarray
    cls_pstart: np.ndarray
    dpos: np.ndarray
    dcol: np.ndarray
    full_space: bool


class ScanTables(NamedTuple):
    """`kernels.soft_band`: the codebook transposed as 0 / -1 masks."""

    masks_t: np.ndarray


class FoldTables(NamedTuple):
    """`kernels.soft_band_fold`: block / row bits and sign tables of the folded transform, and
    masks_t for the exact 64-bit redo."""

    fold_b: int
    fold_v: int
    fold_sgn: np.ndarray
    fold_row: np.ndarray
    fold_usign: np.ndarray
    masks_t: np.ndarray


class HardTables(NamedTuple):
    """`kernels.hard_lean`: per-position syndrome / information bits, coset leaders' information
    bits and weights, the column of each information pattern, d_min."""

    syn_col: np.ndarray
    info_bit: np.ndarray
    leader_info: np.ndarray
    leader_wt: np.ndarray
    col_of_info: np.ndarray
    d_min: int


class NaryTables(NamedTuple):
    """`kernels.soft_nary`: alphabet size and the (size, n) uint8 codebook."""

    q: int
    codebook: np.ndarray


def _path_tables(cls: type, doc: str) -> functools.cached_property:
    """A cached `CodeTables` property: the NamedTuple `cls` of the attributes named like its fields."""
    def build(self: "CodeTables"):
        return cls(*(getattr(self, f) for f in cls._fields))
    build.__doc__ = doc
    return functools.cached_property(build)


@dataclass(frozen=True, eq=False)
class CodeTables:
    """Packed codebook and search structures of a code (see module docstring).

    Attributes (binary codes; N-ary codes only fill ``codebook``):
        n, k, q, size: code parameters; size = number of codewords (columns).
        codebook: (size, n) uint8 symbols.
        masks: (size,) uint64 packed codewords (bit i = frame i).
        info: (k,) int64 information positions, or empty if none found.
        comp_info: (ceil(n/8), 256) int64 byte tables; OR of the looked-up entries packs the
            information bits of a mask into a k-bit index.
        col_of_info: (2**k,) int32 column of each information pattern.
        linear: the codeword set is closed under XOR (a binary linear code).
        comp_syn: (ceil(n/8), 256) int64 byte tables packing the J bits (syndrome) of a mask.
        leader: (2**(n-k),) uint64 coset leaders (minimum-weight masks), empty if too large.
        diff_masks, diff_info: nonzero codewords sorted by (weight, pattern on group 0), and
            their packed information bits.
        class_start: (n + 2,) int64 start of each weight class in diff_* (class t = weight t).
        sub_start: (S + 1,) int64 starts of sublists sharing weight and group-0 pattern.
        sub_p0, sub_weight: (S,) int64 group-0 pattern and weight of each sublist.
        class_sub: (n + 2,) int64 first sublist of each weight class.
        column_linear: linear and the column index is a message (see module docstring).
        full_space: column-linear and every n-bit word a codeword (size == 2**n, e.g. gray-n):
            the lane search resolves a pixel's zero-cost ties directly (`kernels.lanes`).
        syn_col: (n,) int64 syndrome of the unit word e_i (the syndrome of h is the XOR of
            syn_col over the set bits of h); info_bit: (n,) int64 information-set index bits of e_i.
        col_bit: (n,) int64 column contribution of e_i (column-linear codes, else zeros).
        leader_col, leader_info: (2**(n-k),) int64 column contribution / information bits of
            each coset leader; leader_wt: (2**(n-k),) int32 leader weight (= Hamming distance).
        cls_weight: (C,) int64 weights of the nonzero codewords, ascending; cls_start: (C + 1,)
            int64 first codeword of each class in dcol; cls_pstart: (C,) int64 first position of
            each class in dpos (class c holds (cls_start[c+1] - cls_start[c]) * cls_weight[c]).
        dpos: int32 positions of every nonzero codeword (class by class); dcol: int32 columns.
        masks_t: (n, size) int32 codebook transposed, -1 where the bit is 1, else 0 (band scan).
        fold_b, fold_v: column bits of a block / of a row of `kernels.soft_band_fold`
            (column-linear codes; 0 otherwise).
        fold_sgn: (n, 2**fold_v) int64 parity of g_i & v (g_i: the column bits whose XOR is
            bit i of the codeword); fold_row: (n,) int64 row bits (g_i >> fold_v) of the block;
            fold_usign: (2**(k - fold_b), n) int64 parity of g_i & (u << fold_b) for block u.
    """

    n: int
    k: int
    q: int
    size: int
    d_min: int
    codebook: np.ndarray
    masks: np.ndarray
    info: np.ndarray
    comp_info: np.ndarray
    col_of_info: np.ndarray
    linear: bool
    comp_syn: np.ndarray
    leader: np.ndarray
    diff_masks: np.ndarray
    diff_info: np.ndarray
    class_start: np.ndarray
    sub_start: np.ndarray
    sub_p0: np.ndarray
    sub_weight: np.ndarray
    class_sub: np.ndarray
    column_linear: bool = False
    full_space: bool = False
    syn_col: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    info_bit: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    col_bit: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    leader_col: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    leader_info: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    leader_wt: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    cls_weight: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    cls_start: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    cls_pstart: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    dpos: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    dcol: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    masks_t: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.int32))
    fold_b: int = 0
    fold_v: int = 0
    fold_sgn: np.ndarray = field(default_factory=lambda: np.zeros((0, 1), np.int64))
    fold_row: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    fold_usign: np.ndarray = field(default_factory=lambda: np.zeros((1, 0), np.int64))

    @property
    def has_info(self) -> bool:
        return self.info.size == self.k and self.k > 0

    @property
    def has_leader(self) -> bool:
        return self.leader.size > 0

    scalar_tables = _path_tables(ScalarTables, "Tables of `kernels.soft_binary` (any binary code).")
    lane_tables = _path_tables(LaneTables, "Tables of `kernels.soft_lanes` (column-linear codes).")
    scan_tables = _path_tables(ScanTables, "Tables of `kernels.soft_band` (any binary code).")
    fold_tables = _path_tables(FoldTables, "Tables of `kernels.soft_band_fold` (column-linear codes).")
    hard_tables = _path_tables(HardTables, "Tables of `kernels.hard_lean` (binary linear codes with coset leaders).")
    nary_tables = _path_tables(NaryTables, "Tables of `kernels.soft_nary` (any code).")


def pack_masks(codebook: np.ndarray) -> np.ndarray:
    """(M, n) 0/1 rows -> (M,) uint64 with bit i = column i (n <= 64): `edge.codes.words.pack_words`."""
    cb = np.asarray(codebook)
    n = cb.shape[1]
    if n > 64:
        raise ValueError(f"binary decoders support n <= 64 frames, got n={n}")
    return pack_words(cb)


def _compress_tables(positions: np.ndarray, n: int) -> np.ndarray:
    """Byte tables that gather the bits at `positions` of a mask into consecutive bits 0.."""
    nbytes = max(1, (n + 7) // 8)
    table = np.zeros((nbytes, 256), dtype=np.int64)
    values = np.arange(256, dtype=np.int64)
    for out_bit, pos in enumerate(positions):
        g, b = divmod(int(pos), 8)
        table[g] |= ((values >> b) & 1) << out_bit
    return table


def _compress(masks: np.ndarray, table: np.ndarray) -> np.ndarray:
    out = np.zeros(masks.shape, dtype=np.int64)
    m = masks.astype(np.uint64)
    for g in range(table.shape[0]):
        out |= table[g][((m >> np.uint64(8 * g)) & np.uint64(255)).astype(np.int64)]
    return out


def _independent_columns(cb: np.ndarray) -> list[int]:
    """Greedy set of codebook positions whose columns (as GF(2) vectors over rows) are independent."""
    return independent(as_ints(cb.T))


def _information_set(cb: np.ndarray, k: int) -> np.ndarray:
    """k positions on which the codebook is a bijection onto k-bit strings, or empty."""
    size, n = cb.shape
    candidates = [list(range(k))]
    indep = _independent_columns(cb)
    if len(indep) >= k:
        candidates.append(indep[:k])
    for pos in candidates:
        pos_arr = np.array(pos, dtype=np.int64)
        idx = pack_words(cb[:, pos_arr]).astype(np.int64)
        if np.unique(idx).size == size:
            return pos_arr
    return np.zeros(0, dtype=np.int64)


def _coset_leaders(masks: np.ndarray, comp_syn: np.ndarray, comp_info: np.ndarray,
                   col_of_info: np.ndarray, n: int, r: int) -> np.ndarray:
    """Minimum-weight error mask of every syndrome (2**r entries), by increasing weight."""
    leader = np.zeros(2**r, dtype=np.uint64)
    found = np.zeros(2**r, dtype=bool)
    found[0] = True
    remaining = 2**r - 1
    # Errors of weight w: syndrome of e = J-bits of (e xor encode(info bits of e)).
    frontier = np.zeros(1, dtype=np.uint64)
    weight = 0
    while remaining > 0 and weight < n:
        weight += 1
        # Extend every frontier pattern by one bit above its highest set bit (each set once).
        highest = np.where(frontier == 0, -1, np.floor(np.log2(np.maximum(frontier, 1).astype(np.float64))).astype(np.int64))
        new = []
        for b in range(n):
            sel = frontier[highest < b]
            if sel.size:
                new.append(sel | np.uint64(1 << b))
        frontier = np.concatenate(new) if new else np.zeros(0, dtype=np.uint64)
        if frontier.size == 0:
            break
        enc = masks[col_of_info[_compress(frontier, comp_info)]]
        syn = _compress(frontier ^ enc, comp_syn)
        order = np.argsort(syn, kind="stable")
        syn_s, fr_s = syn[order], frontier[order]
        first = np.ones(syn_s.size, dtype=bool)
        first[1:] = syn_s[1:] != syn_s[:-1]
        syn_u, fr_u = syn_s[first], fr_s[first]
        new_mask = ~found[syn_u]
        leader[syn_u[new_mask]] = fr_u[new_mask]
        found[syn_u[new_mask]] = True
        remaining -= int(new_mask.sum())
    if remaining:
        raise AssertionError("coset leader search did not cover every syndrome")
    return leader


@functools.lru_cache(maxsize=32)
def _tables_cached(code: Code) -> CodeTables:
    cb = np.asarray(code.codebook, dtype=np.uint8)
    size, n = cb.shape
    k = code.k
    empty64 = np.zeros(0, dtype=np.int64)
    emptyu = np.zeros(0, dtype=np.uint64)
    if code.q != 2:
        return CodeTables(
            n=n, k=k, q=code.q, size=size, d_min=code.d_min, codebook=cb, masks=emptyu,
            info=empty64, comp_info=np.zeros((1, 256), np.int64), col_of_info=np.zeros(0, np.int32),
            linear=False, comp_syn=np.zeros((1, 256), np.int64), leader=emptyu, diff_masks=emptyu,
            diff_info=empty64, class_start=np.zeros(n + 2, np.int64), sub_start=np.zeros(1, np.int64),
            sub_p0=empty64, sub_weight=empty64, class_sub=np.zeros(n + 2, np.int64),
        )
    masks = pack_masks(cb)
    info = _information_set(cb, k)
    comp_info = _compress_tables(info, n)
    col_of_info = np.full(2**k, -1, dtype=np.int32)
    if info.size == k:
        col_of_info[_compress(masks, comp_info)] = np.arange(size, dtype=np.int32)
    mask_set = set(masks.tolist())
    linear = bool(info.size == k and 0 in mask_set and size > 0)
    if linear:
        # closed under XOR iff every sum of two "unit" codewords is in the set; check all pairs
        # against the basis (codewords with one information bit set) plus a full membership test.
        units = masks[col_of_info[1 << np.arange(k)]]
        sums = np.zeros(size, dtype=np.uint64)
        idx = _compress(masks, comp_info)
        for t in range(k):
            sums ^= np.where((idx >> t) & 1, units[t], np.uint64(0))
        linear = bool(np.array_equal(sums, masks))
    comp_syn = np.zeros((1, 256), np.int64)
    leader = emptyu
    if linear:
        rest = np.setdiff1d(np.arange(n), info)
        comp_syn = _compress_tables(rest, n)
        if n - k <= MAX_SYNDROME_BITS:
            leader = _coset_leaders(masks, comp_syn, comp_info, col_of_info, n, n - k)
    diff_masks = emptyu
    diff_info = empty64
    class_start = np.zeros(n + 2, np.int64)
    sub_start = np.zeros(1, np.int64)
    sub_p0 = empty64
    sub_weight = empty64
    class_sub = np.zeros(n + 2, np.int64)
    if linear:
        nz = masks[masks != 0]
        weight = np.bitwise_count(nz).astype(np.int64)
        p0 = (nz & np.uint64((1 << GROUP_BITS) - 1)).astype(np.int64)
        order = np.lexsort((p0, weight))
        diff_masks = np.ascontiguousarray(nz[order])
        diff_info = _compress(diff_masks, comp_info)
        weight, p0 = weight[order], p0[order]
        class_start = np.searchsorted(weight, np.arange(n + 2)).astype(np.int64)
        key = weight * (1 << GROUP_BITS) + p0
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if key.size else empty64
        sub_start = np.r_[starts, key.size].astype(np.int64)
        sub_p0 = p0[starts].astype(np.int64)
        sub_weight = weight[starts].astype(np.int64)
        class_sub = np.searchsorted(sub_weight, np.arange(n + 2)).astype(np.int64)
    lanes = _lane_tables(cb, masks, linear, info, comp_info, comp_syn, col_of_info, leader, diff_masks)
    return CodeTables(
        n=n, k=k, q=2, size=size, d_min=code.d_min, codebook=cb, masks=masks, info=info,
        comp_info=comp_info, col_of_info=col_of_info, linear=linear, comp_syn=comp_syn,
        leader=leader, diff_masks=diff_masks, diff_info=diff_info, class_start=class_start,
        sub_start=sub_start, sub_p0=sub_p0, sub_weight=sub_weight, class_sub=class_sub, **lanes,
    )


def _lane_tables(cb, masks, linear, info, comp_info, comp_syn, col_of_info, leader, diff_masks) -> dict:
    """Fields of `CodeTables` used by the lane-parallel kernels (see module docstring)."""
    size, n = cb.shape
    out: dict = {"masks_t": np.ascontiguousarray(-cb.T.astype(np.int32))}
    if not linear:
        return out
    size_bits = int(size).bit_length() - 1
    idx = np.arange(size, dtype=np.int64)
    acc = np.zeros(size, dtype=np.uint64)
    for b in range(size_bits):
        acc ^= np.where((idx >> b) & 1, masks[1 << b], np.uint64(0))
    column_linear = bool(size == 1 << size_bits and np.array_equal(acc, masks))
    units = bit_weights(n)
    info_bit = _compress(units, comp_info)
    syn_col = _compress(units ^ masks[col_of_info[info_bit]], comp_syn)
    out.update(column_linear=column_linear, info_bit=info_bit, syn_col=syn_col)
    if leader.size:
        leader_info = _compress(leader, comp_info)
        out.update(leader_info=leader_info, leader_wt=np.bitwise_count(leader).astype(np.int32))
    if not column_linear:
        return out
    out["col_bit"] = col_of_info[info_bit].astype(np.int64)
    out["full_space"] = bool(size == 1 << n)
    out.update(_fold_tables(masks, size_bits, n))
    if leader.size:
        out["leader_col"] = col_of_info[out["leader_info"]].astype(np.int64)
    weight = np.bitwise_count(diff_masks).astype(np.int64)  # diff_masks are sorted by weight
    cls_weight, cls_count = np.unique(weight, return_counts=True)
    bits = unpack_words(diff_masks, n).astype(bool)
    out.update(
        cls_weight=cls_weight.astype(np.int64),
        cls_start=np.r_[0, np.cumsum(cls_count)].astype(np.int64),
        cls_pstart=np.r_[0, np.cumsum(cls_count * cls_weight)[:-1]].astype(np.int64),
        dpos=np.nonzero(bits)[1].astype(np.int32),
        dcol=col_of_info[_compress(diff_masks, comp_info)].astype(np.int32),
    )
    return out


def _fold_tables(masks: np.ndarray, size_bits: int, n: int) -> dict:
    """`CodeTables` fold_* fields of a column-linear code (see `kernels.soft_band_fold`)."""
    b = min(FOLD_BLOCK_BITS, size_bits)
    v = min(FOLD_LANE_BITS, b)
    g = np.zeros(n, np.int64)  # bit i of masks[col] = parity(g_i & col)
    for j in range(size_bits):
        g |= unpack_words(masks[1 << j], n).astype(np.int64) << j
    def parity(x):
        return (np.bitwise_count(np.asarray(x, np.int64)) & 1).astype(np.int64)
    return {
        "fold_b": b, "fold_v": v,
        "fold_sgn": np.ascontiguousarray(parity(g[:, None] & np.arange(1 << v)[None, :])),
        "fold_row": ((g >> v) & ((1 << (b - v)) - 1)).astype(np.int64),
        "fold_usign": np.ascontiguousarray(parity(np.arange(1 << (size_bits - b))[:, None] & (g >> b)[None, :])),
    }


def code_tables(code: Code) -> CodeTables:
    """Lookup tables of `code` (cached per Code instance)."""
    if code.q == 2 and code.n > 64:
        raise ValueError(f"code {code.name!r}: binary decoders support n <= 64 frames, got n={code.n}")
    return _tables_cached(code)

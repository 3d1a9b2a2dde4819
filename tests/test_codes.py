"""Code library: exact d_min of named codes, families, shortening, column order, table, search."""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes import Code, best, get_code, griesmer_bound, names
from edge.codes.code import encode_messages, int_to_digits, pairwise_min_distance
from edge.codes.families import bch, bch_generator_poly, bch_table, hamming, reed_muller
from edge.codes.gfq import gf_inv, gf_mul
from edge.codes.linear import column_messages, golay, shorten
from edge.codes.nary import qary_gray_digits, reed_solomon, reed_solomon_generator_poly
from edge.codes.words import pack_words as _pack  # the one bit-packing function
from edge.codes.search import (
    _weight_profile, search_code, search_cyclic, search_generator_columns, search_parity_columns,
)
from edge.codes.table import KNOWN_K10, table_for_k

EXPECTED_D_MIN = {
    "binary-10": 1, "gray-10": 1, "gray-8": 1, "xor02-10": 1, "xor04-10": 1,
    "ecc-15-10": 4, "ecc-15-11": 3, "ecc-20-8": 8, "ecc-22-10": 8, "ecc-31-10": 12, "ecc-63-10": 27,
    "xor02-10+crc5": 4, "gray-10+crc5": 4, "xor04-10+crc5": 4, "gray-10+crc5-0x05": 3,
    "gray-10+crc5-0x09": 3, "xor02-10+crc5-0x05": 3, "xor02-10+crc5-0x09": 3,
    "hamming-7-4": 3, "hamming-15-11": 3, "ext-hamming-16-11": 4, "bch-15-7": 5, "bch-31-11": 11,
    "ext-bch-32-11": 12, "bch-63-10": 27, "bch-127-8": 63, "rm-1-5": 16, "rm-2-5": 8, "rm-1-4": 8,
    "golay-23-12": 7, "golay-24-12": 8,
    "ternary-golay-11-6": 5, "ternary-golay-12-6": 6, "rs8-7-3": 5, "rs8-6-3": 4, "rs16-15-4": 12,
    "rs16-12-3": 10, "nary3-6": 1, "nary8-3": 1,
}


@pytest.mark.parametrize("name", sorted(EXPECTED_D_MIN))
def test_named_code_exact_d_min(name):
    code = get_code(name)
    assert code.name == name
    assert code.d_min == EXPECTED_D_MIN[name]
    assert code.codebook.shape == (code.q**code.k, code.n)
    assert code.codebook.dtype == np.uint8


def test_every_listed_name_builds():
    for name in names():
        assert get_code(name).name == name


@pytest.mark.parametrize("name", ["ecc-22-10", "xor02-10+crc5", "ecc-15-10", "rs8-7-3", "ternary-golay-12-6"])
def test_d_min_matches_pairwise_brute_force(name):
    code = get_code(name)
    assert pairwise_min_distance(code.codebook) == code.d_min


def test_named_sizes():
    assert (get_code("ecc-22-10").n, get_code("ecc-22-10").k) == (22, 10)
    assert get_code("ecc-63-10").n == 63 and get_code("ecc-63-10").d_min >= 27
    assert (get_code("rs8-7-3").q, get_code("rs16-15-4").q, get_code("ternary-golay-12-6").q) == (8, 16, 3)
    assert "Golay" in get_code("ecc-22-10").construction
    assert "BCH" in get_code("ecc-31-10").construction and "shortened by 1" in get_code("ecc-31-10").construction


def test_unknown_name_lists_valid_names():
    with pytest.raises(ValueError, match="valid names: .*ecc-22-10"):
        get_code("ecc-twenty-two")


def test_codes_are_cached_and_read_only():
    a = get_code("ecc-22-10")
    assert get_code("ecc-22-10") is a
    with pytest.raises(ValueError):
        a.codebook[0, 0] = 1


@pytest.mark.parametrize("name", ["ecc-15-10", "ecc-22-10", "ecc-31-10", "ecc-63-10", "gray-10+crc5",
                                  "hamming-15-11", "rm-1-5", "rs16-12-3", "ternary-golay-12-6", "nary8-3"])
def test_systematic_bits_equal_message(name):
    code = get_code(name)
    assert code.systematic
    np.testing.assert_array_equal(code.codebook[:, : code.k], int_to_digits(code.messages, code.k, code.q))
    np.testing.assert_array_equal(code.encode(code.messages), code.codebook)


@pytest.mark.parametrize("build,lengths", [
    (lambda: golay(True), [1, 2, 4, 6]),
    (lambda: bch(31, 11, extended=True), [1, 3, 5]),
    (lambda: hamming(4, extended=True), [1, 4, 7]),
    (lambda: bch(63, 16), [2, 6]),
])
def test_shortening_keeps_d_min_and_is_a_subcode(build, lengths):
    base = build()
    base_words = {bytes(row) for row in base.codebook}
    for length in lengths:
        short = shorten(base, length)
        assert (short.n, short.k) == (base.n - length, base.k - length)
        assert short.d_min >= base.d_min
        assert short.systematic
        np.testing.assert_array_equal(short.codebook[:, : short.k], int_to_digits(short.messages, short.k))
        padded = np.concatenate([np.zeros((short.size, length), np.uint8), short.codebook], axis=1)
        assert all(bytes(row) in base_words for row in padded)


def test_paper_shortened_codes():
    assert shorten(bch(31, 11, extended=True), 1).d_min == 12  # (32,11,12) -> (31,10,12)
    assert shorten(golay(True), 2).d_min == 8  # (24,12,8) -> (22,10,8)


def test_bch_table_and_generator_polynomials_match_galois():
    # generator polynomials as printed by galois 0.4 (galois.BCH(...).generator_poly,
    # galois.ReedSolomon(15, 11).generator_poly); see tools/check_codes_galois.py
    assert bch_generator_poly(15, 7) == (0b111010001, 5)
    assert bch_generator_poly(31, 11)[0] == 1451733
    assert reed_solomon_generator_poly(16, 15, 11) == [7, 8, 12, 13, 1]
    assert [k for k, _, _ in bch_table(15)] == [11, 7, 5, 1]
    assert [k for k, _, _ in bch_table(31)] == [26, 21, 16, 11, 6, 1]
    assert (63, 10) == (get_code("bch-63-10").n, get_code("bch-63-10").k)
    with pytest.raises(ValueError, match="no binary BCH code"):
        bch(31, 12)


def test_reed_muller_parameters():
    for r, m in [(1, 3), (1, 4), (2, 4), (1, 5)]:
        c = reed_muller(r, m)
        assert c.n == 2**m and c.d_min == 2 ** (m - r)


def test_gf_arithmetic_gf8_is_not_mod_q():
    # alpha^3 = alpha + 1 in GF(8) with x^3 + x + 1: 2 * 4 = 3; integers mod 8 would give 0
    assert int(gf_mul(2, 4, 8)) == 3
    for a in range(1, 16):
        assert int(gf_mul(a, gf_inv(a, 16), 16)) == 1
    code = get_code("rs8-7-3")
    plain = (int_to_digits(code.messages, code.k, 8).astype(np.int64) @ code.generator) % 8
    assert not np.array_equal(plain, code.codebook)  # why Code.encode is field-aware
    np.testing.assert_array_equal(encode_messages(code.messages, code.generator, 8), code.codebook)
    assert code.codebook.max() == 7


def test_qary_gray_neighbours_differ_in_one_digit():
    d = qary_gray_digits(4, 3).astype(int)
    steps = np.abs(np.diff(d, axis=0))
    assert np.all((steps != 0).sum(axis=1) == 1) and steps.max() == 1
    assert len({tuple(r) for r in d}) == 81
    # q-ary Gray message order: neighbouring columns differ in one message digit, so their
    # codewords are exactly d_min apart (a linear code's minimum-weight difference).
    for name, d in [("ternary-golay-12-6", 6), ("rs8-7-3", 5), ("nary3-6", 1)]:
        code = get_code(name)
        assert code.d_min == d
        assert np.all(code.neighbour_distances() == d), name


@pytest.mark.parametrize("name,d", [("ecc-15-10", 4), ("ecc-22-10", 8), ("ecc-31-10", 12), ("gray-10", 1)])
def test_neighbour_distances_equal_d_min_in_gray_order(name, d):
    nd = get_code(name).neighbour_distances()
    assert nd.shape == (1023,)
    assert np.all(nd == d)


def test_binary_order_available_and_worse():
    code = get_code("ecc-22-10")
    from edge.codes.linear import from_generator

    binary = from_generator(code.generator, name="b", family="golay", construction="", order="binary")
    np.testing.assert_array_equal(binary.messages, np.arange(1024))
    assert binary.d_min == 8 and binary.neighbour_distances().max() > 8
    assert set(column_messages(code.generator, "gray")) == set(range(1024))


def test_transitions_per_frame():
    t = get_code("gray-10").transitions_per_frame()
    np.testing.assert_array_equal(t, 2 ** np.arange(10))


def test_griesmer_bound():
    assert [griesmer_bound(n, 10) for n in (10, 15, 22, 31, 64)] == [1, 4, 8, 12, 30]
    for n, (lo, hi) in KNOWN_K10.items():
        assert griesmer_bound(n, 10) >= hi


def test_table_k10_against_known_values():
    cells = table_for_k(10)
    assert sorted(cells) == list(range(10, 64))
    for n, cell in cells.items():
        assert cell.d_min <= griesmer_bound(n, 10)
        if n in KNOWN_K10:
            assert cell.d_min <= KNOWN_K10[n][1]
    got = {n: cells[n].d_min for n in (15, 19, 20, 21, 22, 31, 63)}
    assert got == {15: 4, 19: 5, 20: 6, 21: 7, 22: 8, 31: 12, 63: 27}
    assert cells[22].family == "golay" and cells[31].family == "bch"


def test_best_returns_exact_code():
    for n, k in [(22, 10), (31, 10), (27, 10), (13, 8)]:
        code = best(n, k)
        assert (code.n, code.k) == (n, k)
        assert code.d_min == table_for_k(k)[n].d_min
    assert get_code("ecc-27-10").d_min == best(27, 10).d_min


def test_best_bad_input():
    with pytest.raises(ValueError, match="n < k"):
        best(5, 10)
    with pytest.raises(ValueError, match="k <= 12"):
        best(40, 13)
    with pytest.raises(ValueError, match="n <= 128"):
        best(200, 10)
    with pytest.raises(ValueError, match="too large for exhaustive"):
        Code(name="big", family="x", codebook=np.zeros((2**14, 20), np.uint8), k=14)


def test_tabu_search_is_deterministic_and_reaches_best_known_d_min():
    a, da, ca = search_generator_columns(20, 8, seed=3, iterations=3000)
    b, db, cb = search_generator_columns(20, 8, seed=3, iterations=3000)
    np.testing.assert_array_equal(a, b)
    assert da == db == 8 and ca == cb  # best known [20, 8] is 8 = Griesmer bound
    cols, d = search_parity_columns(20, 8, seed=3, iterations=3000)
    assert cols.shape == (12,) and d == 8
    # (22, 10): the tabu search alone reaches the best known 8; the Code recomputes d_min exhaustively
    code = search_code(22, 10, method="linear")
    assert code.d_min == 8 and code.systematic and "tabu" in code.construction
    assert search_generator_columns(31, 10, seed=0, iterations=4000)[1] >= 10


def test_cyclic_search_and_registry_reach_the_paper_codes():
    code = get_code("search-31-10")
    assert code.family == "search" and code.systematic and "cyclic" in code.construction
    assert code.d_min == get_code("ecc-31-10").d_min == 12  # exhaustive d_min of the Code
    assert search_code(31, 10, method="cyclic").d_min == 12
    g, d, count, _ = search_cyclic(22, 10)
    assert d == 8 and count == get_code("ecc-22-10").weight_distribution()[8]
    assert get_code("search-22-10").d_min == 8
    # the Gray-code weight kernel agrees with the Code's exhaustive weight distribution
    wd = code.weight_distribution()
    assert _weight_profile(_pack(code.generator)) == (12, wd[12])
    # where the cyclic family is weak the tabu search wins: [40, 10] cyclic gives 10 only
    assert search_code(40, 10, iterations=4000).d_min >= 13


def test_poisson_disk_search_is_nonlinear_and_exact():
    code = get_code("poisson-20-8")
    assert code.generator is None and code.size == 256
    assert code.d_min == pairwise_min_distance(code.codebook) >= 5


def test_search_bad_input():
    with pytest.raises(ValueError, match="k < n"):
        search_code(8, 10)
    with pytest.raises(ValueError, match="k <= 16"):
        search_code(40, 17)
    with pytest.raises(ValueError, match="method"):
        search_code(20, 8, method="anneal")
    with pytest.raises(ValueError, match="iterations"):
        search_generator_columns(20, 8, iterations=0)


def test_nary_bad_input():
    with pytest.raises(ValueError, match="n <= 7"):
        reed_solomon(8, 9, 3)
    with pytest.raises(ValueError, match="codewords"):
        get_code("nary3-11")

"""CRC-appended codes: polynomial conventions, d_min reached, detection of every error of weight < d,
and the EDC polynomial search."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from edge.codes import get_code
from edge.codes.crc import (CRC5_EPC, CRC5_ITU, CRC5_USB, DEFAULT_POLY, crc_bits, crc_code, crc_passes,
                            edc_search, full_polynomial, longest_runs, parity_matrix)


def test_polynomial_given_with_or_without_leading_term():
    assert full_polynomial(0x15, 5) == full_polynomial(0x35, 5) == 0b110101
    a = crc_code(get_code("gray-10"), 0x15, 5)
    b = crc_code(get_code("gray-10"), 0x35, 5)
    np.testing.assert_array_equal(a.codebook, b.codebook)


@pytest.mark.parametrize("poly,width,match", [
    (0x135, 5, "degree 8; expected degree 5"),
    (0x14, 5, "constant term 1"),
    (0x7, 9, "width must be 3..8"),
    (0x3, 2, "width must be 3..8"),
    (-1, 5, "non-negative"),
])
def test_bad_polynomials(poly, width, match):
    with pytest.raises(ValueError, match=match):
        crc_code(get_code("gray-10"), poly, width)


def test_crc_matches_bitwise_long_division():
    rng = np.random.default_rng(0)
    data = rng.integers(0, 2, size=(50, 10)).astype(np.uint8)
    full = full_polynomial(0x15, 5)
    got = crc_bits(data, 0x15, 5)
    for row, crc in zip(data, got):
        value = int("".join(map(str, row)), 2) << 5
        for shift in range(value.bit_length() - 6, -1, -1):
            if value >> (shift + 5) & 1:
                value ^= full << shift
        assert int("".join(map(str, crc)), 2) == value


@pytest.mark.parametrize("base", ["gray-10", "xor02-10", "xor04-10"])
def test_crc5_polynomials_reach_expected_distance(base):
    code = get_code(base)
    assert crc_code(code, CRC5_ITU, 5).d_min == 4
    assert crc_code(code, CRC5_USB, 5).d_min == 3
    assert crc_code(code, CRC5_EPC, 5).d_min == 3


def test_crc_code_keeps_base_frames_and_messages():
    base = get_code("xor02-10")
    code = get_code("xor02-10+crc5")
    np.testing.assert_array_equal(code.codebook[:, :10], base.codebook)
    np.testing.assert_array_equal(code.messages, base.messages)
    assert code.n == 15 and not code.systematic
    assert get_code("gray-10+crc5").systematic


CASES = [("gray-10", w, DEFAULT_POLY[w]) for w in range(3, 9)] + [
    ("gray-10", 5, CRC5_USB), ("gray-10", 5, CRC5_EPC), ("xor02-10", 5, CRC5_ITU), ("gray-8", 4, 0x3),
]


@pytest.mark.parametrize("base,width,poly", CASES)
def test_crc_detects_every_error_below_its_distance(base, width, poly):
    code = crc_code(get_code(base), poly, width)
    words = code.codebook[:: 8]  # 128 codewords of 1024 keep the test fast
    assert crc_passes(code.codebook, poly, width).all()
    n, d = code.n, code.d_min
    assert d >= 2
    for weight in range(1, d):
        for pos in itertools.combinations(range(n), weight):
            err = np.zeros(n, np.uint8)
            err[list(pos)] = 1
            assert not crc_passes(words ^ err, poly, width).any(), (weight, pos)
    # the distance is tight: some error of weight d is not detected
    weights = code.codebook.sum(axis=1)
    undetected = code.codebook[np.flatnonzero(weights == d)[0]]
    assert crc_passes(words[:1] ^ undetected, poly, width).all()


def test_parity_matrix_shape():
    p = parity_matrix(10, 0x15, 5)
    assert p.shape == (10, 5) and p.dtype == np.uint8
    np.testing.assert_array_equal(p[-1], [1, 0, 1, 0, 1])  # x^5 mod g = x^4 + x^2 + 1


def test_longest_runs():
    cb = np.array([[0, 1], [0, 1], [1, 1], [1, 0], [1, 0]], np.uint8)
    np.testing.assert_array_equal(longest_runs(cb), [3, 3])
    np.testing.assert_array_equal(longest_runs(get_code("gray-10").codebook)[-3:], [8, 4, 2])


def test_edc_search_xor02():
    records = edc_search(get_code("xor02-10"), range(3, 7))
    assert len(records) == 4 + 8 + 16 + 32  # odd polynomials of each width
    best = records[0]
    assert (best.width, best.poly, best.d_min, best.n) == (5, 0x15, 4, 15)
    assert best.high_frequency and best.max_stripe <= 4
    # unfavourable: same d_min but a low-frequency CRC frame (appendix E)
    bad = [r for r in records if r.d_min == 4 and not r.high_frequency]
    assert bad and all(r.max_stripe > 4 for r in bad)
    for r in records[::7]:
        assert r.d_min == crc_code(get_code("xor02-10"), r.poly, r.width).d_min
    assert max(r.d_min for r in records if r.width == 3) == 2  # [13, 10, 3] violates the Hamming bound
    assert max(r.d_min for r in records if r.width == 4) == 3  # x^4+x+1: shortened Hamming (14, 10, 3)


def test_edc_search_bad_input():
    with pytest.raises(ValueError, match="3..8"):
        edc_search(get_code("xor02-10"), [2, 3])
    with pytest.raises(ValueError, match="max_stripe"):
        edc_search(get_code("xor02-10"), [3], max_stripe=0)


def test_crc_matches_an_independent_library_for_every_polynomial():
    """crccheck (PyPI, byte-wise table CRC, init 0, no reflection, no final XOR) over leading-zero
    padded data: every polynomial of widths 3..8, with and without the leading term."""
    import crccheck.crc as crccheck  # a test dependency (pyproject [test])
    rng = np.random.default_rng(1)
    for width in range(3, 9):
        for low in range(1, 1 << width, 2):
            class Crc(crccheck.CrcBase):
                _width, _poly, _initvalue = width, low, 0
                _reflect_input = _reflect_output = False
                _xor_output = 0
            data = rng.integers(0, 2, size=(8, 15)).astype(np.uint8)
            for poly in (low, low | (1 << width)):
                got = crc_bits(data, poly, width)
                for row, crc in zip(data, got):
                    padded = np.concatenate([np.zeros(1, np.uint8), row])  # 16 bits, a leading 0 keeps the CRC
                    assert int("".join(map(str, crc)), 2) == Crc.calc(np.packbits(padded).tobytes())


def test_crc_bits_and_check_bad_shapes():
    # a 1-D row raised IndexError; words no longer than the CRC failed in numpy broadcasting
    with pytest.raises(ValueError, match=r"\(M, n_data\)"):
        crc_bits(np.zeros(10, np.uint8), 0x15, 5)
    for shape in [(2, 5), (2, 3), (15,)]:
        with pytest.raises(ValueError, match="n > 5 bits"):
            crc_passes(np.zeros(shape, np.uint8), 0x15, 5)
    assert crc_passes(np.zeros((2, 6), np.uint8), 0x15, 5).all()

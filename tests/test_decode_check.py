"""EDC error maps: check() flags every error pattern of weight < d_min and passes codewords."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode import check, contrast_error_map, error_map


def _frames_of(words: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P, n) 0/1 words -> frames (n, 1, P) uint8 with white 200, black 10."""
    frames = (words.T[:, None, :] * 190 + 10).astype(np.uint8)
    p = words.shape[0]
    return frames, np.full((1, p), 200, np.uint8), np.full((1, p), 10, np.uint8)


def test_codewords_pass():
    code = get_code("ecc-22-10")
    fr, wh, bl = _frames_of(code.codebook)
    assert not check(fr, wh, bl, code).any()
    inv = (210 - fr.astype(np.int64)).astype(np.uint8)
    assert not check(fr, wh, bl, code, inverse=inv).any()


def test_every_error_pattern_below_d_min_is_flagged():
    code = get_code("ecc-22-10")
    assert code.d_min == 8
    rng = np.random.default_rng(0)
    base = code.codebook[rng.integers(0, code.size, 64)]
    for weight in range(1, code.d_min):
        ones = np.array(list(itertools.combinations(range(code.n), weight)))  # (C(n, weight), weight)
        patterns = np.zeros((len(ones), code.n), np.uint8)
        patterns[np.arange(len(ones))[:, None], ones] = 1
        if len(patterns) > 4000:
            patterns = patterns[rng.choice(len(patterns), 4000, replace=False)]
        words = base[np.arange(len(patterns)) % len(base)] ^ patterns
        fr, wh, bl = _frames_of(words)
        assert check(fr, wh, bl, code).all(), f"an error of weight {weight} went undetected"


def test_weight_one_errors_exhaustive_and_gray_detects_nothing():
    code = get_code("ecc-22-10")
    words = (code.codebook[:, None, :] ^ np.eye(code.n, dtype=np.uint8)[None]).reshape(-1, code.n)
    fr, wh, bl = _frames_of(words)
    assert check(fr, wh, bl, code).all()
    gray = get_code("gray-10")
    fr, wh, bl = _frames_of(gray.codebook ^ np.eye(10, dtype=np.uint8)[np.arange(gray.size) % 10])
    assert not check(fr, wh, bl, gray).any()


def test_unused_columns_are_errors():
    code = get_code("gray-10")
    fr, wh, bl = _frames_of(code.codebook)
    err = check(fr, wh, bl, code, columns=768)
    assert not err[0, :768].any() and err[0, 768:].all()


def test_contrast_and_combined_maps():
    wh = np.array([[200, 30]], np.uint8)
    bl = np.array([[10, 20]], np.uint8)
    assert contrast_error_map(wh, bl, 40 / 255).tolist() == [[False, True]]
    code = get_code("ecc-22-10")
    words = code.codebook[:2].copy()
    words[1, 0] ^= 1
    fr, _, _ = _frames_of(words)
    fr = np.minimum(fr, 30).astype(np.uint8)
    fr[:, 0, 0] = np.where(code.codebook[0] == 1, 200, 10)
    fr[:, 0, 1] = np.where(words[1] == 1, 30, 20)
    both = error_map(fr, wh, bl, code, contrast_threshold=40 / 255)
    assert both.tolist() == [[False, True]]


def test_check_bad_input():
    code = get_code("ecc-22-10")
    with pytest.raises(ValueError, match="n=22"):
        check(np.zeros((3, 2, 2), np.uint8), np.ones((2, 2), np.uint8), np.zeros((2, 2), np.uint8), code)

"""The one coded-capture type, the one full-scale rule, the one bit order, the one GF(2) elimination,
and uint16 / bit_depth decoding."""

from __future__ import annotations

import numpy as np
import pytest

from edge.capture import CodedCapture, NoiseModel, full_scale
from edge.codes import get_code
from edge.codes.gf2 import independent, rank, systematic_form
from edge.codes.gfq import systematic_form_q
from edge.codes.words import columns_of_words, membership_table, pack_words, packed_codewords, unpack_words
from edge.decode import check, check_capture, decode, decode_capture
from edge.decode.check import lookup_columns
from edge.decode.inputs import validate
from edge.decode.synthetic import make_capture
from edge.decode.tables import code_tables

# These tests check the candidate search against brute force and the contrast / confidence rule:
# decode under that rule (the "error" rule's posterior re-orders candidates; its own exactness
# tests are in tests/test_decode_posterior.py).
from functools import partial as _partial  # noqa: E402

from edge.decode import decode as _decode  # noqa: E402

decode = _partial(_decode, validity="confidence")
decode_capture = _partial(decode_capture, validity="confidence")


def test_full_scale_is_one_rule():
    assert full_scale(np.uint8) == 255.0
    assert full_scale(np.uint16) == 65535.0
    assert full_scale(np.uint16, 12) == 4095.0
    assert full_scale(np.uint16, 10) == 1023.0
    assert full_scale(np.float32) == 1.0 and full_scale(np.float64, 12) == 1.0
    with pytest.raises(ValueError, match="bit_depth: expected 1..16 for uint16"):
        full_scale(np.uint16, 17)
    with pytest.raises(ValueError, match="expected dtype uint8, uint16"):
        full_scale(np.int32)
    # every place that had its own rule now agrees
    from edge.device import full_scale as max_value
    from edge.sim import CameraModel

    for bits in (8, 10, 12, 16):
        fs = full_scale(np.uint8 if bits == 8 else np.uint16, bits)
        assert CameraModel(bits=bits).levels == fs == max_value(bits)


def test_coded_capture_fields_and_validation():
    code = get_code("gray-10")
    f = np.zeros((code.n, 2, 3), np.uint16)
    w = np.full((2, 3), 4000, np.uint16)
    b = np.zeros((2, 3), np.uint16)
    cap = CodedCapture(f, w, b, code=code, bit_depth=12, frame_exposure=[2.0] * code.n + [2.0, 2.0],
                       exposure_unit="us", noise=NoiseModel(0.01, 0.02))
    assert cap.shape == (2, 3) and cap.n == code.n and cap.bits == 12
    assert cap.full_scale == 4095.0 and cap.scale == 1.0 / 4095.0
    assert cap.exposure == 2.0 and np.array_equal(cap.exposure_ratio, np.ones(code.n))
    with pytest.raises(ValueError, match="frame_exposure: expected 12 values"):
        CodedCapture(f, w, b, frame_exposure=[1.0] * code.n)
    # NaN / negative exposures made exposure_ratio NaN or negative; 0 means "not known" (recordings)
    for bad in (np.nan, -1.0, np.inf):
        with pytest.raises(ValueError, match="frame_exposure: expected finite exposures >= 0"):
            CodedCapture(f, w, b, frame_exposure=[1.0] * code.n + [bad, 1.0])
    unknown = CodedCapture(f, w, b, frame_exposure=np.zeros(code.n + 2))
    assert unknown.exposure == 0.0 and unknown.exposure_ratio is None
    with pytest.raises(ValueError, match="exposure_unit"):
        CodedCapture(f, w, b, exposure_unit="ms")
    with pytest.raises(ValueError, match="does not carry"):
        CodedCapture(f, w, b).exposure
    st = validate(f, w, b, code, bit_depth=12)
    assert isinstance(st, CodedCapture) and st.scale == 1.0 / 4095.0
    assert validate(f, w, b, code).scale == 1.0 / 4095.0  # no bit_depth: detected (largest value 4000: 12 bits)
    assert validate(f, w * 10, b, code).scale == 1.0 / 65535.0 and validate(f, w // 20, b, code).bit_depth == 8
    with pytest.raises(ValueError, match="values up to 4000 exceed the full scale 1023 of bit_depth=10"):
        validate(f, w, b, code, bit_depth=10)
    for bad in (12.5, "12", True):
        with pytest.raises(ValueError, match="bit_depth: expected an integer"):
            validate(f, w, b, code, bit_depth=bad)
    with pytest.raises(ValueError, match="normalised to"):
        validate(f.astype(np.float32), w.astype(np.float32), b.astype(np.float32), code)
    # uint8 follows the same rule (full_scale): bit_depth 1..8 holding every value, 8 where not given
    f8, w8, b8 = f.astype(np.uint8), w.astype(np.uint8) // 20, b.astype(np.uint8)
    assert validate(f8, w8, b8, code).scale == validate(f8, w8, b8, code, bit_depth=8).scale == 1 / 255
    assert validate(f8, w8, b8, code, bit_depth=4).scale == 1 / 15
    with pytest.raises(ValueError, match="bit_depth: expected 1..8 for uint8 frames, got 12"):
        validate(f8, w8, b8, code, bit_depth=12)


def test_uint16_bit_depth_decodes_like_float():
    """12-bit data in uint16 with bit_depth=12 decodes like the same data as float; without
    bit_depth the bit depth is detected from the data (12), so it decodes the same as with it
    (before, it was read as 16-bit, 16x darker, and the contrast floor left most pixels out).

    The service's path: disparity band, uint16 and float32 frames (the kernels the suite compiles
    anyway).  float32 holds raw / 4095 to 2**-24, so a cost may round the other way: "like" is
    the same column and validity on all but a few pixels in a thousand."""
    code = get_code("ecc-22-10")
    rng = np.random.default_rng(7)
    h, w = 16, 128
    x = np.arange(w)[None, :]
    cols = np.clip(x - rng.integers(10, 40, size=(h, w)), 0, code.size - 1)
    band = {"min_disparity": 0, "max_disparity": 64}
    cap = make_capture(code, cols, rng=rng, albedo=rng.uniform(0.05, 0.8, (h, w)), sigma_s=0.03,
                       dtype=np.uint16, bit_depth=12)
    assert cap.frames.max() <= 4095 and cap.frames.max() > 2048 and cap.bit_depth == 12
    raw = (cap.frames, cap.white, cap.black)

    def as_float(full: float):
        return [(a.astype(np.float64) / full).astype(np.float32) for a in raw]

    def alike(d1, d2):
        same = (d1.column == d2.column) & (d1.valid == d2.valid)
        assert same.mean() >= 0.995, same.mean()
        np.testing.assert_allclose(d1.confidence[same], d2.confidence[same], atol=2e-3)

    d12 = decode(*raw, code, bit_depth=12, **band)
    alike(d12, decode(*as_float(4095.0), code, **band))
    assert (d12.column == cols)[d12.valid].mean() > 0.99 and d12.valid.mean() > 0.8
    dc = decode_capture(cap, code, **band)  # decode_capture unpacks bit_depth itself
    assert np.array_equal(dc.column, d12.column) and np.array_equal(dc.valid, d12.valid)
    detected = decode(*raw, code, **band)  # without bit_depth: detected as 12 bits
    assert np.array_equal(detected.column, d12.column) and np.array_equal(detected.valid, d12.valid)
    for rule in ({"validity": "confidence"}, {"method": "hard"}):  # the rules with an absolute contrast floor
        stated, found = decode(*raw, code, bit_depth=12, **rule, **band), decode(*raw, code, **rule, **band)
        assert np.array_equal(stated.valid, found.valid) and stated.valid.mean() > 0.5, rule
        assert decode(*raw, code, bit_depth=16, **rule, **band).valid.mean() < 0.8 * stated.valid.mean(), rule
    wide = decode(*raw, code, bit_depth=16, **band)  # stated 16 bits: 16x darker, as the float data / 65535
    alike(wide, decode(*as_float(65535.0), code, **band))
    assert wide.valid.mean() < d12.valid.mean()


def test_producers_make_coded_captures():
    from edge.sim import CameraModel, capture_code, make_scene

    code = get_code("gray-8")
    cam = CameraModel(bits=12)
    scene = make_scene("plane", 64, 16, seed=0)
    cap = capture_code(scene, code, cam, rng=0, stripe=4)
    assert isinstance(cap, CodedCapture) and cap.frames.dtype == np.uint16 and cap.bit_depth == 12
    assert cap.exposure == cam.frame_exposure(code.n) and cap.frame_exposure.shape == (code.n + 2,)
    assert cap.noise == NoiseModel(cam.sigma_r, cam.sigma_s) and cap.stripe == 4 and cap.bits == 12
    syn = make_capture(code, np.zeros((2, 3), np.int64), rng=np.random.default_rng(0))
    assert isinstance(syn, CodedCapture) and syn.truth.shape == (2, 3) and syn.code is code
    assert np.array_equal(check_capture(syn), check(syn.frames, syn.white, syn.black, code))


def test_one_bit_order():
    code = get_code("ecc-22-10")
    cb = code.codebook
    words = pack_words(cb)
    assert np.array_equal(words, (cb.astype(np.uint64) << np.arange(code.n, dtype=np.uint64)).sum(axis=1))
    assert np.array_equal(unpack_words(words, code.n), cb)
    assert np.array_equal(code_tables(code).masks, words)  # the decoder's masks
    assert np.array_equal(packed_codewords(code), words.astype(np.int64))  # the EDC's
    assert np.array_equal(membership_table(code)[words.astype(np.int64)], np.arange(code.size))
    # frame 0 is the least significant bit
    assert pack_words(np.array([1, 0, 0])) == 1 and pack_words(np.array([0, 0, 1])) == 4
    assert pack_words(np.array([2, 0, 1]), q=3) == 2 + 9
    # the table look-up and the sorted look-up (n > 22) agree
    long = get_code("golay-24-12")
    lw = pack_words(long.codebook)
    assert np.array_equal(columns_of_words(lw, long), np.arange(long.size))
    assert (columns_of_words(lw ^ np.uint64(1), long) == -1).all()


def test_lookup_columns_equals_check_with_inverse():
    code = get_code("ecc-15-10")
    rng = np.random.default_rng(1)
    cols = rng.integers(0, code.size, size=(6, 40))
    cap = make_capture(code, cols, rng=rng, sigma_s=0.2, inverse=True)
    col = lookup_columns(cap.frames, cap.white, cap.black, code, inverse=cap.inverse)
    err = check(cap.frames, cap.white, cap.black, code, inverse=cap.inverse)
    assert np.array_equal(col < 0, err) and err.any() and (~err).any()
    assert (col[~err] == cols[~err]).mean() > 0.9


def test_gf2_elimination():
    rng = np.random.default_rng(2)
    for _ in range(20):
        g = rng.integers(0, 2, size=(5, 9)).astype(np.uint8)
        r = rank(g)
        combos = (np.arange(32)[:, None] >> np.arange(5)) & 1  # every GF(2) combination of the rows
        span = {tuple(v) for v in (combos @ g) % 2}
        assert len(span) == 2**r  # the span of a rank-r set has 2**r vectors
        assert len(independent(int("".join(map(str, row)), 2) for row in g)) == r
    g = np.array([[1, 1, 0, 1], [0, 1, 1, 1]], np.uint8)
    s = systematic_form(g)
    assert s.dtype == np.uint8 and np.array_equal(s[:, :2], np.eye(2, dtype=np.uint8))
    assert np.array_equal(s, systematic_form_q(g, 2)) and rank(np.vstack([s, g])) == 2
    with pytest.raises(ValueError, match="information set"):
        systematic_form(np.array([[0, 1], [0, 1]], np.uint8))

"""Decoder inputs as a library user hands them over: byte order, bit depth of every dtype, the
capture facts (columns, stripe), the code and settings objects, and the EDC maps of uint16 data."""

from __future__ import annotations

import numpy as np
import pytest

from edge.capture import CodedCapture, full_scale
from edge.codes import get_code
from edge.decode import DecodeSettings, check, contrast_error_map, decode, decode_capture, decode_refined, error_map
from edge.decode.inputs import validate
from edge.decode.kernels import LANES
from edge.decode.synthetic import make_capture

FIELDS = ("column", "confidence", "valid", "candidates", "distances", "error")


def _capture(name: str, *, dtype=np.uint16, bit_depth: int | None = 12, inverse: bool = False, h: int = 5,
             w: int = LANES + 9, seed: int = 3) -> CodedCapture:
    code = get_code(name)
    rng = np.random.default_rng(seed)
    cols = np.clip(np.arange(w)[None, :] + 40 + rng.integers(0, 3, (h, w)), 0, code.size - 1)
    return make_capture(code, cols, rng=rng, albedo=rng.uniform(0.05, 0.5, (h, w)), sigma_s=0.06, dtype=dtype,
                        bit_depth=bit_depth, inverse=inverse)


def _swapped(a: np.ndarray | None) -> np.ndarray | None:
    """The same values in the other byte order (big-endian on the usual machines)."""
    return None if a is None else a.astype(a.dtype.newbyteorder("S"))


def _same(a, b) -> None:
    for f in FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        assert (x is None and y is None) or np.array_equal(x, y, equal_nan=True), f


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_other_byte_order_decodes_like_native(dtype):
    """A big-endian capture (``>u2`` from a file or a camera SDK) decodes to the same arrays as
    its native copy; it was refused as "expected dtype uint16, got >u2".  `validate` hands every
    backend and search path the native copy (checked here), so the paths need no run of their
    own on swapped input (each would compile its kernels once more for nothing: minutes on a
    cold 2-core CI machine)."""
    cap = _capture("ecc-22-10", dtype=dtype, bit_depth=12 if dtype == np.uint16 else None)
    code = cap.code
    fr, wh, bl = _swapped(cap.frames), _swapped(cap.white), _swapped(cap.black)
    assert not fr.dtype.isnative and np.array_equal(fr, cap.frames)
    st, native = validate(fr, wh, bl, code), validate(cap.frames, cap.white, cap.black, code)
    for a, b in ((st.frames, native.frames), (st.white, native.white), (st.black, native.black)):
        assert a.dtype == b.dtype and a.dtype.isnative and a.flags.c_contiguous and np.array_equal(a, b)
    assert st.scale == native.scale and st.bits == native.bits
    settings = ({}, {"validity": "confidence"}, {"min_disparity": -60, "max_disparity": -30}, {"method": "hard"},
                {"method": "sgm"}) if dtype == np.uint16 else ({},)
    for kw in settings:
        _same(decode(fr, wh, bl, code, **kw), decode(cap.frames, cap.white, cap.black, code, **kw))
    assert np.array_equal(check(fr, wh, bl, code), check(cap.frames, cap.white, cap.black, code))
    assert np.array_equal(contrast_error_map(wh, bl, 0.05), contrast_error_map(cap.white, cap.black, 0.05))
    assert full_scale(np.dtype(">u2"), 12) == full_scale(np.uint16, 12) == 4095.0


def test_other_byte_order_inverse_frames():
    cap = _capture("gray-10", inverse=True)
    args = (cap.frames, cap.white, cap.black, cap.code)
    _same(decode(*args, inverse=_swapped(cap.inverse)), decode(*args, inverse=cap.inverse))


def test_bit_depth_is_one_rule_for_every_dtype():
    """bit_depth follows `edge.capture.full_scale` for uint8 as for uint16 (it was ignored for
    uint8 frames: bit_depth=12 on uint8, e.g. 12-bit data cast to uint8, decoded silently, and a
    CodedCapture that full_scale refuses decoded); a bit_depth that is not an integer is one
    error for any dtype (it was ignored for uint8 and floats)."""
    cap = _capture("ecc-22-10", dtype=np.uint8, bit_depth=None)
    args = (cap.frames, cap.white, cap.black, cap.code)
    _same(decode(*args, bit_depth=8), decode(*args))
    with pytest.raises(ValueError, match="bit_depth: expected 1..8 for uint8 frames, got 12"):
        decode(*args, bit_depth=12)
    with pytest.raises(ValueError, match="exceed the full scale 63 of bit_depth=6"):
        decode(*args, bit_depth=6)
    as_capture = CodedCapture(cap.frames, cap.white, cap.black, code=cap.code, bit_depth=12)
    with pytest.raises(ValueError, match="bit_depth: expected 1..8 for uint8 frames, got 12"):
        decode_capture(as_capture)
    with pytest.raises(ValueError, match="bit_depth: expected 1..8"):
        as_capture.full_scale
    # 6-bit samples in uint8 decode as the same samples in uint16 at bit_depth=6
    six = (cap.frames // 4, cap.white // 4, cap.black // 4)
    _same(decode(*six, cap.code, bit_depth=6, validity="confidence"),
          decode(*(a.astype(np.uint16) for a in six), cap.code, bit_depth=6, validity="confidence"))
    fl = tuple(a.astype(np.float32) / 255 for a in args[:3])
    for bad in ("12", 12.0, True):
        for arrays in (args[:3], fl):
            with pytest.raises(ValueError, match="bit_depth: expected an integer number of bits"):
                decode(*arrays, cap.code, bit_depth=bad)
        with pytest.raises(ValueError, match="bit_depth: expected an integer"):
            full_scale(np.uint16, bad)


@pytest.mark.parametrize("name,value", [("columns", 2.5), ("columns", "700"), ("columns", True), ("stripe", 1.5),
                                        ("stripe", "2"), ("stripe", None), ("stripe", np.float64(2.0))])
def test_columns_and_stripe_are_integers(name, value):
    """columns=2.5 decoded silently with 2 rows, stripe=1.5 with stripe 1 in the search but 1.5
    in the error rule's choices, and stripe="2" / None failed in a comparison (TypeError
    '<' not supported); each is now one ValueError naming the argument."""
    cap = _capture("ecc-22-10")
    args = (cap.frames, cap.white, cap.black, cap.code)
    with pytest.raises(ValueError, match=f"{name}: expected an integer"):
        decode(*args, **{name: value})
    if name == "columns":
        with pytest.raises(ValueError, match="columns: expected an integer"):
            check(*args, columns=value)
    ok = {"columns": np.int64(700), "stripe": np.int32(2)}[name]
    assert decode(*args, **{name: ok}).column.shape == cap.shape


def test_code_and_settings_objects_are_checked():
    """A code's name or a dict of options where a Code / DecodeSettings goes raised
    AttributeError from inside the decoder ('str' object has no attribute 'size')."""
    cap = _capture("ecc-22-10")
    args = (cap.frames, cap.white, cap.black)
    with pytest.raises(TypeError, match="code: expected an edge.codes.Code"):
        decode(*args, "ecc-22-10")
    with pytest.raises(TypeError, match="code: expected an edge.codes.Code"):
        check(*args, "ecc-22-10")
    with pytest.raises(TypeError, match="settings: expected a DecodeSettings or None"):
        decode(*args, cap.code, settings={"method": "list"})
    assert decode(*args, cap.code, settings=DecodeSettings(method="list")).column.shape == cap.shape


def test_refit_iterations_are_an_integer():
    """decode_refined(iterations=1.5) failed in range() with a TypeError."""
    cap = _capture("ecc-22-10")
    args = (cap.frames, cap.white, cap.black, cap.code)
    for bad in (1.5, "2", True):
        with pytest.raises(ValueError, match="iterations: expected an integer >= 0"):
            decode_refined(*args, iterations=bad)
    assert decode_refined(*args, iterations=np.int64(2)).column.shape == cap.shape


def test_edc_maps_read_uint16_at_the_detected_bit_depth():
    """error_map / contrast_error_map of 12-bit data in uint16 without bit_depth read it at
    16 bits (a 0.04 threshold became 2621 counts) and flagged every pixel; they now read it at
    the bit depth decode reads it at, so the maps equal those with bit_depth=12 and of the
    normalised floats."""
    cap = _capture("ecc-22-10", h=8, w=40)
    args = (cap.frames, cap.white, cap.black, cap.code)
    stated = error_map(*args, bit_depth=12)
    assert 0 < stated.mean() < 0.5
    assert np.array_equal(error_map(*args), stated)
    fl = tuple(a.astype(np.float64) / 4095 for a in args[:3])
    assert np.array_equal(error_map(*fl, cap.code), stated)
    assert np.array_equal(contrast_error_map(cap.white, cap.black, 0.04),
                          contrast_error_map(cap.white, cap.black, 0.04, bit_depth=12))
    assert np.array_equal(contrast_error_map(cap.white, cap.black, 0.04),
                          contrast_error_map(fl[1], fl[2], 0.04))
    with pytest.raises(ValueError, match="white: values up to .* exceed the full scale 255 of bit_depth=8"):
        contrast_error_map(cap.white, cap.black, 0.04, bit_depth=8)
    with pytest.raises(ValueError, match="white: expected dtype uint8, uint16"):
        contrast_error_map(cap.white.astype(np.int32), cap.black.astype(np.int32), 0.04)
    with pytest.raises(ValueError, match="normalised to"):
        contrast_error_map(cap.white.astype(np.float32), cap.black.astype(np.float32), 0.04)

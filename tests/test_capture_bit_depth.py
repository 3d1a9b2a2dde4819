"""One bit-depth rule: 12-bit frames in uint16 read at full scale 4095 through every entry point.

`edge.capture.CodedCapture` built without a bit depth read uint16 frames at 65535 (the dtype's
width) while `edge.decode.decode` detects the depth from the samples
(`edge.capture.bit_depth_of`), so ``CodedCapture.scale`` of 12-bit data was 16x off the scale
the decoder used.  Now the capture applies the same rule and stores the depth it found.
"""

from __future__ import annotations

import numpy as np
import pytest

from edge.capture import DETECTED_DEPTHS, CodedCapture, bit_depth_of
from edge.codes import get_code
from edge.decode import decode, decode_capture
from edge.decode.inputs import validate
from edge.decode.synthetic import make_capture

BAND = {"min_disparity": 0, "max_disparity": 64}


def _twelve_bit(h: int = 8, w: int = 96, seed: int = 7):
    """(code, frames, white, black, true columns): 12-bit samples (max in 2048..4095) in uint16."""
    code = get_code("ecc-22-10")
    rng = np.random.default_rng(seed)
    cols = np.clip(np.arange(w)[None, :] - rng.integers(10, 40, size=(h, w)), 0, code.size - 1)
    cap = make_capture(code, cols, rng=rng, albedo=rng.uniform(0.05, 0.8, (h, w)), sigma_s=0.03,
                       dtype=np.uint16, bit_depth=12)
    assert 2048 <= int(cap.white.max()) <= 4095
    return code, cap.frames, cap.white, cap.black, cols


def _same(a, b) -> None:
    assert np.array_equal(a.column, b.column) and np.array_equal(a.valid, b.valid)
    assert np.array_equal(a.confidence, b.confidence)


def test_bit_depth_rule_lives_with_the_capture():
    """`edge.decode.inputs` uses the capture's rule (one definition, below the decoder)."""
    import edge.decode.inputs as inputs

    assert inputs.bit_depth_of is bit_depth_of
    assert not hasattr(inputs, "DETECTED_DEPTHS")
    assert DETECTED_DEPTHS == (8, 10, 12, 14, 16)


def test_coded_capture_without_bit_depth_reads_12_bit_data_at_4095():
    code, f, w, b, _ = _twelve_bit()
    cap = CodedCapture(f, w, b, code=code)
    assert cap.bit_depth == 12 and cap.bits == 12
    assert cap.full_scale == 4095.0 and cap.scale == 1.0 / 4095.0  # was 65535 and 1 / 65535
    assert cap.scale == validate(f, w, b, code).scale == CodedCapture(f, w, b, code=code, bit_depth=12).scale
    np.testing.assert_array_equal(cap.normalised(w), w.astype(np.float64) * (1.0 / 4095.0))
    # the other byte order reads the same
    swapped = [a.astype(a.dtype.newbyteorder("S")) for a in (f, w, b)]
    assert CodedCapture(*swapped, code=code).bit_depth == 12
    # the inverse frames count: a brighter inverse stack lifts the depth as it does in validate
    inv = np.full_like(f, 5000)
    assert CodedCapture(f, w, b, inverse=inv, code=code).bit_depth == validate(f, w, b, code, inverse=inv).bit_depth == 14


def test_coded_capture_keeps_a_stated_depth_and_other_dtypes():
    code, f, w, b, _ = _twelve_bit()
    assert CodedCapture(f, w, b, code=code, bit_depth=16).scale == 1.0 / 65535.0  # stated: not detected
    assert CodedCapture(f // 16, w // 16, b // 16, code=code).bit_depth == 8  # 8-bit data in uint16
    f8, w8, b8 = (np.minimum(a, 255).astype(np.uint8) for a in (f, w, b))
    assert CodedCapture(f8, w8, b8, code=code).bit_depth is None and CodedCapture(f8, w8, b8).scale == 1 / 255
    ff, wf, bf = (a.astype(np.float32) / 4095 for a in (f, w, b))
    assert CodedCapture(ff, wf, bf).bit_depth is None and CodedCapture(ff, wf, bf).scale == 1.0


def test_every_entry_point_decodes_12_bit_data_alike():
    """decode (detected and stated) and decode_capture of a capture with and without a depth."""
    code, f, w, b, cols = _twelve_bit()
    stated = decode(f, w, b, code, bit_depth=12, **BAND)
    assert stated.valid.mean() > 0.5 and (stated.column == cols)[stated.valid].mean() > 0.95
    _same(decode(f, w, b, code, **BAND), stated)
    _same(decode_capture(CodedCapture(f, w, b, code=code), **BAND), stated)
    _same(decode_capture(CodedCapture(f, w, b, code=code, bit_depth=12), **BAND), stated)
    for rule in ({"validity": "confidence"}, {"method": "hard"}):  # absolute contrast floors
        _same(decode_capture(CodedCapture(f, w, b, code=code), **rule, **BAND),
              decode(f, w, b, code, bit_depth=12, **rule, **BAND))


def test_service_decode_path_reads_a_12_bit_camera_at_4095(monkeypatch):
    """The runtime's stack (`Stack.coded`, the profile's camera bits) has the scale `decode`
    detects for the same frames, and the service decodes them to the same columns."""
    from tests._service_helpers import load_test_profile

    from edge.runtime import assembly
    from edge.runtime.assembly import Stack
    from edge.runtime.pipeline import DepthPipeline
    from edge.sensors.sim import SimSensor

    profile = load_test_profile(camera={"bits": 12})
    pipe = DepthPipeline(profile)
    sensor = SimSensor(profile, stacks=1, max_speed=True)
    images = sensor.render_stack(0)
    # a dim scene (its brightest sample under 2048): still above 10 bits' full scale, so the
    # detected depth is the camera's 12 (darker data would be detected as 10: a stated depth wins)
    assert images.dtype == np.uint16 and 1023 < int(images.max()) <= 4095
    stack = Stack(0, tuple(sensor._record(img, i, 0, i) for i, img in enumerate(images)), 0)
    built: list[CodedCapture] = []
    coded = assembly.Stack.coded
    monkeypatch.setattr(assembly.Stack, "coded", lambda self, *a, **k: built.append(coded(self, *a, **k)) or built[-1])
    decoded: list = []
    run = pipe.decode
    monkeypatch.setattr(pipe, "decode", lambda *a: decoded.append(run(*a)) or decoded[-1])
    pipe.process(stack)
    (cap,), (service,) = built, decoded
    n = pipe.n
    f, w, b = images[:n], images[n], images[n + 1]
    assert cap.bit_depth == 12 and cap.scale == 1.0 / 4095.0 == CodedCapture(f, w, b, code=pipe.code).scale
    band = {"min_disparity": profile.decoder.min_disparity, "max_disparity": profile.decoder.max_disparity,
            "columns": pipe.columns, "stripe": pipe.stripe}
    alone = decode(f, w, b, pipe.code, settings=pipe.settings, **band)  # no bit depth: detected
    assert alone.valid.mean() > 0.3
    _same(service, alone)
    _same(decode_capture(CodedCapture(f, w, b, code=pipe.code), settings=pipe.settings, **band), alone)


@pytest.mark.parametrize("top, depth", [(255, 8), (256, 10), (1023, 10), (4095, 12), (4096, 14), (65535, 16)])
def test_detected_depth_is_the_smallest_common_width(top, depth):
    f = np.zeros((2, 2, 3), np.uint16)
    w = np.full((2, 3), top, np.uint16)
    assert CodedCapture(f, w, np.zeros_like(w)).bit_depth == depth == bit_depth_of([("white", w)], None)


def test_a_synthetic_uint16_capture_states_the_depth_it_was_quantised_at():
    """`make_capture` quantises uint16 at 65535 without a bit depth; a dark capture of it must not be
    read at a detected 14-bit scale (its CodedCapture states 16)."""
    from edge.codes import get_code
    from edge.decode.synthetic import make_capture

    cap = make_capture(get_code("gray-10"), np.full((2, 3), 7), rng=np.random.default_rng(0), albedo=0.1,
                       ambient=0.01, dtype=np.uint16)
    assert int(max(cap.frames.max(), cap.white.max())) < 2**14  # dark enough to be detected as 14-bit
    assert cap.bit_depth == 16 and cap.scale == 1 / 65535

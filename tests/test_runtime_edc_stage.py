"""The EDC stage publishes, next to every column, a confidence that belongs to that column."""

from __future__ import annotations

import numpy as np

from tests._service_helpers import load_test_profile

from edge.runtime.assembly import StackAssembler
from edge.runtime.depth import confidence_to_u8
from edge.runtime.edc_stage import GUESS_CONFIDENCE, run_adaptive
from edge.runtime.pipeline import DepthPipeline
from edge.sensors.sim import SimSensor


def _one_stack(sensor, schedule):
    asm = StackAssembler(schedule)
    stack = None
    while stack is None:
        frame = sensor.read(5.0)
        stack = asm.push(frame) if frame is not None else None
    return stack


def test_edc_confidence_belongs_to_the_published_column():
    # v-groove: inter-reflections, so later rounds change some guesses away from the soft decode
    profile = load_test_profile(edc={"rounds": 3}, sim={"scene": "v-groove"})
    pipe = DepthPipeline(profile)
    sensor = SimSensor(profile, stacks=1, max_speed=True)
    sensor.start()
    try:
        stack = _one_stack(sensor, pipe.schedule)
        masked = sensor.capture_masked
        images = pipe.stacked(stack.frames)
        decoded = pipe.decode(images[: pipe.n], images[pipe.n], images[pipe.n + 1])
        soft_col = np.where(pipe.validity(decoded), np.asarray(decoded.column, np.int32), np.int32(-1))
        soft_conf = np.asarray(decoded.confidence, np.float32)
        out = run_adaptive(pipe, stack, images, soft_col, soft_conf, masked)
        published = pipe.process(stack, masked)  # the same rounds through the pipeline
    finally:
        sensor.stop()
    col, conf, verified = out.column, out.confidence, out.verified
    assert out.rounds >= 2
    assert np.array_equal(published.column, col)
    assert np.array_equal(published.confidence, confidence_to_u8(conf, published.depth_mm > 0))
    valid = col >= 0
    same = valid & (col == soft_col)
    verified_other = valid & ~same & verified
    guessed_other = valid & ~same & ~verified
    assert same.sum() > 0.9 * valid.sum()
    assert np.array_equal(conf[same], soft_conf[same])           # the soft decoder's own column
    assert (conf[verified_other] == 1.0).all()                    # an exact, checked codeword
    # a later round's unverified guess is not published as an exact codeword: lowest valid confidence
    assert guessed_other.any(), "the scene should produce later-round guesses (the case under test)"
    assert (conf[guessed_other] == GUESS_CONFIDENCE).all()
    assert (published.confidence[guessed_other] == 1).all()
    assert (published.confidence[~valid] == 0).all()


def _overloads() -> dict:
    """Every live numba CPU dispatcher's compiled signatures (compiled or loaded from the cache)."""
    import gc

    from numba.core.registry import CPUDispatcher

    def dispatcher(obj) -> bool:
        try:
            return isinstance(obj, CPUDispatcher)
        except ReferenceError:  # a weak proxy whose referent is gone (numba's, of a collected function)
            return False

    return {id(d): (d.py_func.__qualname__, frozenset(d.overloads)) for d in gc.get_objects() if dispatcher(d)}


def test_warm_up_leaves_nothing_to_compile_for_the_first_stack():
    """`DepthPipeline.warm_up` covers every kernel a real stack with EDC rounds needs: the first
    stack adds no signature to any numba dispatcher (none compiled, none loaded from the cache),
    so an empty cache stalls start-up, not the first stacks."""
    profile = load_test_profile(edc={"rounds": 1}, sim={"scene": "v-groove"})
    pipe = DepthPipeline(profile)
    sensor = SimSensor(profile, stacks=1, max_speed=True)
    sensor.start()
    try:
        stack = _one_stack(sensor, pipe.schedule)
        pipe.warm_up()
        before = _overloads()
        result = pipe.process(stack, sensor.capture_masked)
        after = _overloads()
    finally:
        sensor.stop()
    assert result.edc_rounds >= 1
    new = sorted(name for key, (name, sigs) in after.items() if sigs != before.get(key, (name, frozenset()))[1])
    assert not new, f"compiled or loaded by the first stack, not by warm_up: {new}"

"""The device model: one set of profile-derived facts that sensors and pipelines share; the
pipeline kind declared in the profile; the pipeline protocol and registry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from edge.device import PIPELINES, DeviceModel, PipelineSpec, default_pipeline, pipeline_kind
from edge.profiles import ProfileError, apply_update, load_profile
from edge.runtime.pipeline import DepthPipeline
from edge.runtime.pipelines import Pipeline, make_pipeline, pipeline_class
from edge.sensors import open_sensor

SHIPPED = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "firmware_profiles").glob("*.toml"))


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_profiles_declare_the_kind_they_used_to_infer(name):
    p = load_profile(name)
    assert p.sensor.pipeline in PIPELINES
    # without the key a profile keeps working: the default is derived the way it always was
    undeclared = apply_update(p, {"sensor": {"pipeline": ""}})
    assert pipeline_kind(undeclared) == p.sensor.pipeline
    assert default_pipeline(p.projector.kind, p.sensor.backend) == p.sensor.pipeline
    model = DeviceModel.from_profile(p)
    pipe = make_pipeline(p)
    assert isinstance(pipe, Pipeline) and model.pipeline == p.sensor.pipeline
    assert type(pipe) is pipeline_class(model.pipeline)
    assert np.array_equal(pipe.schedule, model.schedule) and pipe.full_scale == model.full_scale == 2 ** p.camera.bits - 1
    assert not model.schedule.flags.writeable


@pytest.mark.parametrize("name", ["sim-dlp", "event-dots", "light-curtain", "oak-d-pro"])
def test_sensor_and_pipeline_agree_on_the_device(name):
    p = load_profile(name)
    sensor = open_sensor(p, "sim", max_speed=True)
    pipe = make_pipeline(p)
    assert np.array_equal(sensor.info.schedule, pipe.schedule)
    model = DeviceModel.from_profile(p)
    if model.pipeline in ("dots", "event-dots"):  # what the projector shows is the matching reference
        assert np.array_equal(sensor.pattern, pipe.reference > 0)
    if model.pipeline == "event-dots":
        assert sensor.slot_us == pipe.slot_us == model.slot_us == round(1e6 / p.projector.rate_hz)
    if model.pipeline == "curtain":
        band = p.decoder
        sweep = [model.curtain_disparity(k) for k in range(16)]
        assert sweep[0] == band.max_disparity and min(sweep) == band.min_disparity and sweep[:8] == sweep[8:]


def test_declared_pipeline_is_validated():
    p = load_profile("sim-dlp")
    with pytest.raises(ProfileError, match=r"sensor\.pipeline: expected a pipeline that reads a 'columns' projector"):
        apply_update(p, {"sensor": {"pipeline": "curtain"}})
    with pytest.raises(ProfileError, match=r"sensor\.pipeline: expected one of '', 'columns'.*got 'laser'"):
        apply_update(p, {"sensor": {"pipeline": "laser"}})
    events = load_profile("event-dots")
    # the kind, not the backend, chooses the chain: an event profile declared "dots" runs the frame pipeline
    frames = apply_update(events, {"sensor": {"pipeline": "dots"}})
    assert pipeline_kind(frames) == "dots" and type(make_pipeline(frames)).__name__ == "DotsPipeline"
    with pytest.raises(ValueError, match="unknown pipeline kind 'laser'"):
        pipeline_class("laser")


class TaggedPipeline(DepthPipeline):
    """A pipeline kind added by the test: the columns chain, tagged."""

    tagged = True


def test_a_new_pipeline_kind_is_one_registry_line(monkeypatch):
    monkeypatch.setitem(PIPELINES, "tagged-columns", PipelineSpec("columns", f"{__name__}:TaggedPipeline"))
    p = apply_update(load_profile("sim-dlp"), {"sensor": {"pipeline": "tagged-columns"}})
    pipe = make_pipeline(p)
    assert isinstance(pipe, TaggedPipeline) and isinstance(pipe, Pipeline)
    assert np.array_equal(open_sensor(p, "sim").info.schedule, pipe.schedule)

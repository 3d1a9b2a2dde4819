"""Service lifecycle with the simulated sensor: clean stop, stale-stack drops, config updates."""

from __future__ import annotations

import itertools
import threading

import numpy as np
import pytest

from _service_helpers import NumpyPipeline, load_test_profile, slow_pipeline
from edge.runtime.service import ConfigRejected, Service
from edge.sensors.sim import SimSensor


class Collect:
    def __init__(self):
        self.results = []
        self.status = []
        self.closed = False

    def on_result(self, r):
        self.results.append(r)

    def on_status(self, s):
        self.status.append(s)

    def close(self):
        self.closed = True


def test_service_runs_n_stacks_and_stops_cleanly():
    profile = load_test_profile()
    sink = Collect()
    service = Service(profile, SimSensor(profile, max_speed=True), sinks=[sink], pipeline_factory=NumpyPipeline)
    status = service.run(stacks=3)
    assert status["stacks_decoded"] == 3 and len(sink.results) == 3 and sink.closed
    assert sink.status and sink.status[-1]["stacks_decoded"] == 3
    assert not [t for t in threading.enumerate() if t.name.startswith("edge-")]
    r = sink.results[0]
    assert r.depth_mm.dtype == np.uint16 and r.depth_mm.shape == (120, 160)
    assert r.confidence.dtype == np.uint8
    assert r.valid_fraction > 0.5
    # the tilted plane of the test profile lies between 0.7 and 1.6 m
    d = r.depth_mm[r.depth_mm > 0]
    assert 600 < np.median(d) < 1700
    assert [x.stack for x in sink.results] == sorted(x.stack for x in sink.results)


def test_depth_changes_over_time_with_moving_scene():
    profile = load_test_profile()
    sensor = SimSensor(profile, max_speed=True)
    a, b = sensor.scene(0).depth_m, sensor.scene(5).depth_m
    assert np.nanmax(np.abs(a - b)) > 0.005


def test_slow_decoder_drops_whole_stale_stacks_never_mixes():
    profile = load_test_profile()
    sink = Collect()
    seen_frames = []

    class Checking(slow_pipeline(0.15)):
        def process(self, stack, masked_capture=None):
            seen_frames.append([f.stack for f in stack.frames])
            return super().process(stack, masked_capture)

    service = Service(profile, SimSensor(profile, max_speed=True, poses=2), sinks=[sink],
                      pipeline_factory=Checking, queue_capacity=1)
    status = service.run(stacks=4)
    assert status["stacks_dropped_stale"] > 0
    assert status["stacks_dropped"] >= status["stacks_dropped_stale"]
    assert all(len(set(ids)) == 1 for ids in seen_frames)  # never a mix of two stacks
    stacks = [r.stack for r in sink.results]
    assert stacks == sorted(stacks) and len(set(stacks)) == len(stacks)
    assert stacks[-1] - stacks[0] > len(stacks) - 1  # stacks were skipped, i.e. dropped


def test_config_update_validated_live_and_bad_rejected():
    profile = load_test_profile()
    service = Service(profile, SimSensor(profile, max_speed=True), pipeline_factory=NumpyPipeline)
    new = service.update_config({"decoder": {"min_confidence": 0.5}})
    assert new.decoder.min_confidence == 0.5 and service.profile.decoder.min_confidence == 0.5
    with pytest.raises(ValueError, match="decoder.min_confidence"):
        service.update_config({"decoder": {"min_confidence": 7}})
    with pytest.raises(ConfigRejected, match="camera.width"):
        service.update_config({"camera": {"width": 320}})
    with pytest.raises(ValueError, match="unknown key"):
        service.update_config({"decoder": {"bogus": 1}})
    assert service.profile.decoder.min_confidence == 0.5 and service.profile.camera.width == 160
    st = service.status()
    assert st["config_updates"] == 1 and st["config_rejected"] == 3


def test_stop_from_another_thread_while_running():
    profile = load_test_profile()
    service = Service(profile, SimSensor(profile), pipeline_factory=NumpyPipeline)  # real-time pacing
    timer = threading.Timer(0.8, service.stop)
    timer.start()
    status = service.run(seconds=30)
    timer.join()
    assert status["uptime_s"] < 10
    assert not [t for t in threading.enumerate() if t.name.startswith("edge-")]


def test_bad_run_arguments():
    profile = load_test_profile()
    service = Service(profile, SimSensor(profile, max_speed=True), pipeline_factory=NumpyPipeline)
    with pytest.raises(ValueError, match="stacks"):
        service.run(stacks=0)


def test_status_reports_the_decoders_fitted_noise_model():
    """Under the error rule (the test profile's decoder defaults) every result carries the noise
    model its decode fitted, and the status shows the last one as sigmas: the simulated camera's
    (sigma_r 0.004, sigma_s 0.015; 8-bit frames, so the fit sees quantisation too; measured
    0.0038 / 0.0153)."""
    profile = load_test_profile()
    sink = Collect()
    status = Service(profile, SimSensor(profile, max_speed=True), sinks=[sink]).run(stacks=2)
    assert all(r.noise is not None and r.noise[2] for r in sink.results)
    noise = status["noise_model"]
    assert noise["fitted"] and status["noise_fit_fallbacks"] == 0
    assert 0.004 / 2 < noise["sigma_r"] < 0.004 * 2.5 and 0.015 / 1.5 < noise["sigma_s"] < 0.015 * 1.5
    assert not [w for w in status["warnings"] if "noise model" in w]
    from edge.runtime.console import summary_lines  # what `edge run` prints at the end

    line = [x for x in summary_lines(status) if x.startswith("noise model")]
    assert len(line) == 1 and "fitted to the capture" in line[0] and "not fitted" not in line[0]


def test_noise_fit_fallbacks_are_counted_and_warned_when_they_start():
    """A decode that could not fit its noise model (the profile's sigmas stood in) is counted per
    stack, and the first one after a fitted stack adds one warning, not one per stack."""
    pattern = itertools.cycle([False, False, True, False])

    class Fallback(NumpyPipeline):
        def decode(self, codes, white, black):
            out = super().decode(codes, white, black)
            out.stats = {"noise_a": 1e-4, "noise_beta": 9e-4, "noise_fitted": next(pattern)}
            return out

    profile = load_test_profile()
    logged, sink = [], Collect()
    service = Service(profile, SimSensor(profile, max_speed=True), sinks=[sink], pipeline_factory=Fallback,
                      log=logged.append)
    status = service.run(stacks=6)
    flags = [r.noise[2] for r in sink.results]
    starts = sum(1 for i, f in enumerate(flags) if not f and (i == 0 or flags[i - 1]))
    assert len(flags) == 6 and True in flags and starts >= 2
    assert status["noise_fit_fallbacks"] == flags.count(False)
    assert status["noise_model"] == {"sigma_r": 0.01, "sigma_s": 0.03, "fitted": flags[-1]}
    warned = [w for w in status["warnings"] if "noise model could not be fitted" in w]
    assert len(warned) == starts and "sigma_r = 0.01" in warned[0]
    assert len([x for x in logged if "noise model could not be fitted" in x]) == starts
    from edge.runtime.console import summary_lines

    line = [x for x in summary_lines(status) if x.startswith("noise model")][0]
    assert f"{flags.count(False)} stacks not fitted" in line and "sigma_r 0.01," in line


def test_stacks_no_pixel_sees_the_projector_in_are_published_empty():
    """A covered lens or a projector that is off (white <= black everywhere: `NoPatternContrast`)
    is a scene, not a fault: the real decoder's pipeline publishes an empty depth map (depth 0,
    column -1, an all-NaN error image under the error rule) and the service keeps running, past
    the run of consecutive decode errors that would stop it, and decodes again once the pattern
    is back; the status counts the stacks and warns once when they begin."""
    from edge.runtime.pipeline import DepthPipeline
    from edge.runtime.service import MAX_CONSECUTIVE_DECODE_ERRORS

    dark_stacks = MAX_CONSECUTIVE_DECODE_ERRORS + 1
    pattern = iter([False] + [True] * dark_stacks + [False])

    class Covered(DepthPipeline):
        def stacked(self, frames):
            images = super().stacked(frames)
            return np.zeros_like(images) if next(pattern) else images

    profile = load_test_profile()
    logged, sink = [], Collect()
    service = Service(profile, SimSensor(profile, max_speed=True), sinks=[sink], pipeline_factory=Covered,
                      log=logged.append)
    status = service.run(stacks=dark_stacks + 2)
    assert status["stacks_decoded"] == dark_stacks + 2 and status["decode_errors"] == 0 and not service.fault
    assert status["stacks_without_contrast"] == dark_stacks
    dark = sink.results[1:-1]
    assert all(not r.depth_mm.any() and (r.column == -1).all() and not r.confidence.any() for r in dark)
    assert all(r.error is not None and np.isnan(r.error).all() for r in dark)
    for lit in (sink.results[0], sink.results[-1]):
        assert lit.valid_fraction > 0.5 and lit.error is not None and np.isfinite(lit.error[lit.depth_mm > 0]).all()
    warned = [w for w in status["warnings"] if "no pixel sees the projector" in w]
    assert len(warned) == 1 and f"stack {dark[0].stack}:" in warned[0]
    assert len([x for x in logged if "no pixel sees the projector" in x]) == 1


def test_frames_of_another_size_than_the_profile_are_refused():
    """A sensor whose frames are not the profile camera's size (depth and the published intrinsics
    are the profile's) is refused at start with one error naming both sizes; a sensor that states
    the right size but sends other frames gets that error per stack (as a decode error, so the
    service stops after a run of them with it as the fault), not depth of the frames' size."""
    import dataclasses

    from edge.profiles import apply_update

    profile = load_test_profile()
    other = apply_update(profile, {"camera": {"width": 150, "height": 100}})
    with pytest.raises(ValueError, match="sends 150x100 frames, profile .* expects its camera's 160x120"):
        Service(profile, SimSensor(other, max_speed=True), pipeline_factory=NumpyPipeline)

    class Lying(SimSensor):
        def read(self, timeout=None):
            frame = super().read(timeout)
            return None if frame is None else dataclasses.replace(frame, image=frame.image[:100, :150])

    sink = Collect()
    service = Service(profile, Lying(profile, max_speed=True), sinks=[sink], pipeline_factory=NumpyPipeline)
    status = service.run(stacks=2)
    assert not sink.results and status["decode_errors"] >= 1
    assert "expected the profile camera's 160x120 pixels, got 150x100" in status["errors"]

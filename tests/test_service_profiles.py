"""Every shipped profile runs on its simulated backend; event recordings replay bit for bit; bad
event input is dropped and counted."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from _service_helpers import small_event_profile
from edge.profiles import apply_update, list_profiles, load_profile
from edge.runtime.assembly import Stack
from edge.runtime.pipelines import make_pipeline, pipeline_kind
from edge.sensors import open_sensor
from edge.sensors.base import EventSlice
from edge.sim import scene_names

SHIPPED_DIR = Path(__file__).resolve().parents[1] / "firmware_profiles"
SHIPPED = sorted(p.stem for p in SHIPPED_DIR.glob("*.toml"))


class Collect:
    def __init__(self):
        self.results = []

    def on_result(self, r):
        self.results.append(r)

    def on_status(self, s):
        pass

    def close(self):
        pass


def test_every_shipped_profile_loads_and_names_a_simulator_scene():
    from edge.profiles.settings import SimSettings

    assert {"sim-dlp", "oak-d-pro", "event-dots", "light-curtain"} <= set(SHIPPED) <= set(list_profiles())
    assert SimSettings().scene in scene_names()
    for name in SHIPPED:
        p = load_profile(SHIPPED_DIR / f"{name}.toml")
        assert p.sim.scene in scene_names(), f"{name}: sim.scene {p.sim.scene!r} is not a simulator scene"
        make_pipeline(p)  # every shipped profile has a processing chain


def _run_cli_service(name: str, stacks: int = 2, **extra):
    # queue 8: a simulator at full speed on a loaded machine must not drop the first stacks (the
    # queue drops the oldest), whose poses the assertions below were written for
    from edge.commands.run import build_service, load_run_profile

    args = argparse.Namespace(profile=name, sensor="sim", replay=None, record=extra.get("record"), max_speed=True,
                              poses=0, queue=8, no_zenoh=True, listen=None, connect=None, interference=False)
    sink = Collect()
    service = build_service(load_run_profile(args), args, sinks=[sink])
    status = service.run(stacks=stacks)
    return service, status, sink.results


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_profile_runs_two_stacks_on_its_simulator(name):
    service, status, results = _run_cli_service(name)
    assert status["stacks_decoded"] == 2 and status["errors"] == "", status
    assert len(results) == 2
    p = service.profile
    for r in results:
        assert r.depth_mm.dtype == np.uint16 and r.depth_mm.shape == (p.camera.height, p.camera.width)
        assert r.confidence.dtype == np.uint8 and np.all(r.confidence[r.depth_mm == 0] == 0)
        truth = service.sensor.scene(r.stack).depth_m * 1000.0
        ok = r.depth_mm > 0
        rel = np.abs(r.depth_mm[ok] - truth[ok]) / truth[ok]
        kind = pipeline_kind(p)
        if kind == "curtain":
            # detections are the curtain's depth where a surface crosses it: few pixels, all near it
            assert 0.002 < r.valid_fraction < 0.2
            assert np.median(rel) < 0.02 and np.mean(rel < 0.05) > 0.9
        else:
            assert r.valid_fraction > 0.5
            assert np.median(rel) < 0.03, (kind, np.median(rel))
    if pipeline_kind(p) == "event-dots":
        assert status["events_in"] > 0 and status["events_kept"] > 0
        assert status["events_out_of_order"] == 0 and status["events_out_of_bounds"] == 0


def test_curtain_rejects_a_second_device():
    p = load_profile("light-curtain")
    p = apply_update(p, {"camera": {"width": 320, "height": 240}, "projector": {"width": 512, "height": 384},
                         "geometry": {"focal_px": 280.0, "cx_camera": 160.0, "cx_projector": 256.0, "cy": 120.0},
                         "decoder": {"min_disparity": -68, "max_disparity": -28}})
    pipe = make_pipeline(p)
    for interference in (False, True):
        sensor = open_sensor(p, "sim", max_speed=True, interference=interference)
        images = sensor.render_stack(3)
        frames = [dataclasses.replace(_frame(img, i, 3), projector_frame=int(pid))
                  for i, (img, pid) in enumerate(zip(images, pipe.schedule))]
        r = pipe.process(Stack(3, tuple(frames), 0))
        truth = sensor.scene(3).depth_m * 1000.0
        ok = r.depth_mm > 0
        assert ok.sum() > 50
        assert np.mean(np.abs(r.depth_mm[ok] - truth[ok]) / truth[ok] < 0.05) > 0.9, interference


def _frame(image, seq, stack):
    from edge.sensors.base import Frame

    return Frame(image, seq, seq, 1.0, 0, stack)


def small_oak_profile():
    """oak-d-pro at 160 x 100 (its simulator and dot pipeline on a small image)."""
    return apply_update(load_profile("oak-d-pro"), {
        "camera": {"width": 160, "height": 100}, "projector": {"width": 160, "height": 100},
        "geometry": {"focal_px": 95.0, "cx_camera": 80.0, "cx_projector": 80.0, "cy": 50.0},
        "decoder": {"min_disparity": 1, "max_disparity": 24}})


def test_dots_pipeline_stereo_frames_match_reference_mode():
    p = small_oak_profile()
    sensor = open_sensor(p, "sim", max_speed=True)
    pipe = make_pipeline(p)
    images = sensor.render_stack(0)
    mono = pipe.process(Stack(0, tuple(dataclasses.replace(_frame(im, i, 0), projector_frame=int(pid))
                                        for i, (im, pid) in enumerate(zip(images, pipe.schedule))), 0))
    bits = np.array([c == "1" for c in p.code.source], np.uint8)
    right = (sensor.pattern.astype(np.uint8) * 200)[None] * bits[:, None, None]
    stereo = pipe.process(Stack(0, tuple(dataclasses.replace(_frame(np.concatenate([im, r], axis=1), i, 0),
                                                             projector_frame=int(pid))
                                          for i, (im, r, pid) in enumerate(zip(images, right, pipe.schedule))), 0))
    assert mono.valid_fraction > 0.5
    assert np.array_equal(mono.depth_mm, stereo.depth_mm)
    with pytest.raises(ValueError, match="dot frames must be"):
        pipe.process(Stack(0, tuple(dataclasses.replace(_frame(im[:, :50], i, 0), projector_frame=int(pid))
                                    for i, (im, pid) in enumerate(zip(images, pipe.schedule))), 0))


def test_dots_pipelines_publish_no_depth_without_the_own_dots():
    """Block matching returns disparities where the camera sees no dots (a dark scene, the projector
    off): about 10 % of the pixels got depth there; a pixel has depth only where its block holds one
    of the own dots, and a normal stack keeps its depth."""
    from edge.source.events import EVENT_DTYPE

    p = small_oak_profile()
    sensor = open_sensor(p, "sim", max_speed=True)
    pipe = make_pipeline(p)
    images = sensor.render_stack(0)

    def run(frames):
        return pipe.process(Stack(0, tuple(dataclasses.replace(_frame(im, i, 0), projector_frame=int(pid))
                                           for i, (im, pid) in enumerate(zip(frames, pipe.schedule))), 0))

    assert run(images).valid_fraction > 0.5
    for value in (0, 100, 255):  # black, constant, saturated frames
        r = run([np.full_like(im, value) for im in images])
        assert r.valid_fraction == 0.0 and not r.confidence.any() and (r.column == -1).all()
    e = small_event_profile()
    esensor = open_sensor(e, max_speed=True)
    epipe = make_pipeline(e)
    slices = [esensor._record(ev, j, 0, j) for j, ev in enumerate(esensor.render_stack(0))]
    assert epipe.process(Stack(0, tuple(slices), 0)).valid_fraction > 0.3
    empty = [dataclasses.replace(s, events=np.zeros(0, EVENT_DTYPE)) for s in slices]
    assert epipe.process(Stack(0, tuple(empty), 0)).valid_fraction == 0.0


def test_event_slice_message_round_trip():
    from edge.io.event_record import event_slice_message, parse_event_slice
    from edge.source.events import make_events

    ev = make_events([1, 5, 159], [0, 7, 119], [1000, 1001, 1500], [1, -1, 1])
    s = EventSlice(ev, 7, 123456789, 1000.0, 3 << 8, 2, 1000, 2000)
    back = parse_event_slice(event_slice_message(s, 160, 120))
    assert back.events.dtype == ev.dtype and back.events.tobytes() == ev.tobytes()
    assert (back.sequence, back.timestamp_ns, back.projector_frame, back.stack, back.t_start_us, back.t_end_us) == \
        (7, 123456789, 3 << 8, 2, 1000, 2000)
    with pytest.raises(ValueError, match="EventSlice"):
        parse_event_slice(b"\x38\x05")  # count = 5, no columns


class CorruptingSensor:
    """Wraps the event simulator and damages slice 2 of every stack: one event outside the sensor,
    one event out of the slice's time window, one event going back in time."""

    def __init__(self, inner):
        self.inner = inner
        self.info = inner.info

    def start(self):
        self.inner.start()

    def stop(self):
        self.inner.stop()

    def read(self, timeout_s=1.0):
        s = self.inner.read(timeout_s)
        if s is None or s.projector_frame != (2 << 8) or s.events.size < 2:
            return s
        ev = s.events.copy()
        ev["x"][0] = 60000                         # outside the sensor
        extra = ev[-2:].copy()
        extra["t"][0] = s.t_end_us + 5000          # outside the slice's window
        extra["t"][1] = s.t_start_us               # back in time (after later events)
        return dataclasses.replace(s, events=np.concatenate([ev, extra]))


def test_event_service_records_bad_input_counted_and_replays_bit_exact(tmp_path):
    from edge.io.mcap import RecordingReader
    from edge.io.recording import RecordingThread
    from edge.io.replay import replay_recording
    from edge.runtime.service import Service

    p = small_event_profile()
    sensor = CorruptingSensor(open_sensor(p, max_speed=True, interference=True))
    out = tmp_path / "events.mcap"
    rec = RecordingThread(out, p, sensor_metadata=sensor.info.metadata)
    status = Service(p, sensor, recorder=rec, queue_capacity=8).run(stacks=3)
    assert status["stacks_decoded"] == 3 and status["errors"] == "", status
    assert status["events_out_of_bounds"] == 3 and status["events_out_of_window"] == 3
    assert status["events_out_of_order"] == 3
    assert status["recorder"]["frames_lost"] == 0
    reader = RecordingReader(out)
    assert reader.complete
    topics = {m.topic for m in reader.messages()}
    assert "/event-dots/events" in topics and "/event-dots/depth" in topics
    report = replay_recording(out)
    assert report.ok and report.stacks_matched == 3, report.lines()


def test_event_replay_sensor_streams_recorded_slices(tmp_path):
    from edge.commands.sim import record_simulation
    from edge.runtime.service import Service

    p = small_event_profile()
    out = tmp_path / "sim-events.mcap"
    counts = record_simulation(str(out), p, 2)
    assert counts == {"frames": 16, "stacks": 2, "outputs": 2}
    from edge.io.mcap import RecordingReader

    recorded = {o.stack: o.depth_mm for o in RecordingReader(out).outputs()}
    sink = Collect()
    status = Service(p, open_sensor(p, "replay", replay_path=str(out), max_speed=True), sinks=[sink],
                     queue_capacity=8).run()
    assert status["stacks_decoded"] == 2
    # stack by stack (zip() of two lists passed with either of them empty)
    replayed = {r.stack: r.depth_mm for r in sink.results}
    assert sorted(replayed) == sorted(recorded) == [0, 1]
    assert all(np.array_equal(replayed[s], recorded[s]) and replayed[s].any() for s in recorded)


def test_event_pipeline_counts_exactly_and_rejects_frames():
    p = small_event_profile()
    sensor = open_sensor(p, max_speed=True)
    pipe = make_pipeline(p)
    payloads = sensor.render_stack(0)
    slices = [sensor._record(ev, j, 0, j) for j, ev in enumerate(payloads)]
    base = pipe.process(Stack(0, tuple(slices), 0))
    assert base.stats["events_in"] == sum(s.events.size for s in slices)
    assert base.stats["events_out_of_order"] == base.stats["events_out_of_window"] == 0
    bad = list(slices)
    ev = bad[1].events.copy()
    ev["y"][:2] = 500  # outside a 120-row sensor
    late = bad[1].events[:1].copy()
    late["t"] = bad[1].t_start_us - 1  # before the window
    bad[1] = dataclasses.replace(bad[1], events=np.concatenate([ev, late]))
    r = pipe.process(Stack(0, tuple(bad), 0))
    assert r.stats["events_out_of_bounds"] == 2 and r.stats["events_out_of_window"] == 1
    with pytest.raises(ValueError, match="EventSlice"):
        pipe.process(Stack(0, tuple(dataclasses.replace(_frame(np.zeros((120, 160), np.uint8), j, 0),
                                                        projector_frame=int(pid))
                                    for j, pid in enumerate(pipe.schedule)), 0))


def test_columns_pipeline_warm_up_compiles_before_capture():
    """A cold start decodes no stale stack: the compile pause happens before the sensor starts."""
    import time

    from tests._service_helpers import load_test_profile

    from edge.runtime.pipeline import DepthPipeline
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    compile_s = 2.5

    class ColdPipeline(DepthPipeline):
        """Like numba with an empty cache: the first decode compiles, unless warm_up() did it."""

        compiled = False

        def warm_up(self):
            if not ColdPipeline.compiled:
                time.sleep(compile_s)
                ColdPipeline.compiled = True
            return super().warm_up()

        def process(self, stack, masked_capture=None):
            if not ColdPipeline.compiled:
                time.sleep(compile_s)
                ColdPipeline.compiled = True
            return super().process(stack, masked_capture)

    # 30 fps: a stack every 0.8 s, real-time pacing; a compile pause inside capture would let about
    # three stacks pass and the one-stack queue (the default) drop the stale ones
    p = load_test_profile(camera={"rate_hz": 30.0}, projector={"rate_hz": 30.0})
    sink = Collect()
    status = Service(p, SimSensor(p), sinks=[sink], pipeline_factory=ColdPipeline).run(stacks=3)
    assert ColdPipeline.compiled and status["warm_up"]["done"]
    assert [r.stack for r in sink.results] == [0, 1, 2], [r.stack for r in sink.results]
    assert status["stacks_dropped_stale"] == 0 and status["stacks_dropped"] == 0, status
    pipeline = make_pipeline(load_profile("sim-dlp"))
    assert pipeline.warm_up() < 5.0  # kernels are compiled once per process: a second warm-up is cheap

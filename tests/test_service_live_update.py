"""A live config update changes the depth the service publishes once the decode thread swaps the pipeline."""

from __future__ import annotations

import numpy as np
import pytest

from tests._service_helpers import load_test_profile

from edge.runtime.depth import column_to_depth_mm
from edge.runtime.service import Service
from edge.sensors.sim import SimSensor


class Collect:
    def __init__(self):
        self.results = []

    def on_result(self, r):
        self.results.append(r)

    def close(self):
        pass


def test_live_geometry_update_changes_published_depth():
    profile = load_test_profile()
    old_geometry = profile.geometry
    sink = Collect()
    service = Service(profile, SimSensor(profile, max_speed=True), sinks=[sink])
    changed = []

    def uses_new_geometry(r) -> bool:
        return bool(changed) and np.array_equal(r.depth_mm, column_to_depth_mm(r.column, changed[0].geometry))

    def tick(svc):
        if not changed and svc.results_seen >= 2:
            changed.append(svc.update_config({"geometry": {"baseline_m": 2 * old_geometry.baseline_m}}))
        elif changed and sum(map(uses_new_geometry, list(sink.results))) >= 3:
            svc.stop()  # three depth maps after the swap (how many stacks that takes depends on load)

    status = service.run(stacks=40, on_tick=tick)
    assert changed and status["config_updates"] == 1 and status["stacks_decoded"] >= 5
    new_geometry = changed[0].geometry
    assert new_geometry.baseline_m == 2 * old_geometry.baseline_m
    uses_new = []
    for r in sink.results:
        old_depth = column_to_depth_mm(r.column, old_geometry)
        new_depth = column_to_depth_mm(r.column, new_geometry)
        assert r.valid_fraction > 0.5
        is_new = np.array_equal(r.depth_mm, new_depth)
        assert is_new or np.array_equal(r.depth_mm, old_depth)   # one geometry or the other, never a mix
        uses_new.append(is_new)
        if is_new:  # the depth itself changed: same columns, twice the baseline -> about twice the depth
            ok = (r.depth_mm > 0) & (old_depth > 0)
            ratio = r.depth_mm[ok].astype(np.float64) / old_depth[ok]
            assert abs(np.median(ratio) - 2.0) < 0.01
    # the first stacks decoded before the update, every stack after the swap with the new pipeline
    assert uses_new[:2] == [False, False]
    first = uses_new.index(True)
    assert all(uses_new[first:]) and len(uses_new) - first >= 3, uses_new
    assert service.pipeline.geometry == new_geometry


def _record_with_a_live_change(path, update, profile=None, min_files=1, **recording):
    """Run the service (default: the test profile) with a recording; apply `update` after two depth
    maps; stop five maps after the first one the new profile decoded, and not before the recorder
    has opened ``min_files`` files (a rotating recording: how many stacks the recorder keeps up
    with depends on the machine's load and the decoder's speed).  Returns the results and the
    recorded files."""
    from edge.io.recording import RecordingThread
    from edge.sensors import open_sensor

    profile = profile if profile is not None else load_test_profile()
    sink = Collect()
    recorder = RecordingThread(path, profile, **recording)
    service = Service(profile, open_sensor(profile, max_speed=True), sinks=[sink], recorder=recorder)
    changed = []

    def tick(svc):
        if not changed and svc.results_seen >= 2:
            changed.append(svc.update_config(update))
        elif (changed and sum(r.profile == changed[0] for r in list(sink.results)) >= 5
              and len(recorder.files) >= min_files):
            svc.stop()

    try:
        status = service.run(stacks=40, on_tick=tick)
    finally:
        recorder.close()
    assert changed and status["config_updates"] == 1
    return sink.results, recorder.files


def _recorded_profiles(path):
    """[(stack, decoder.method)] of the stacks whose /stack message carries a profile."""
    from edge.io.mcap import RecordingReader

    return [(s.stack, s.info["profile"]["decoder"]["method"]) for s in RecordingReader(path).stacks()
            if s.info and "profile" in s.info]


def test_a_recording_with_a_live_change_replays_bit_for_bit(tmp_path):
    """Every result names the profile that decoded it; the recording marks the first stack the
    changed profile decoded (its /stack message), and replay switches pipelines there: every
    stack matches, before and after the change (before, replay decoded everything with the
    starting profile and every stack after the change differed)."""
    from edge.io.replay import replay_recording

    path = tmp_path / "change.mcap"
    results, _ = _record_with_a_live_change(path, {"decoder": {"method": "median", "max_error": 0.02}})
    methods = [r.profile.decoder.method for r in results]
    first = methods.index("median")
    assert first >= 2 and set(methods[:first]) == {"soft"} and set(methods[first:]) == {"median"}
    assert _recorded_profiles(path) == [(results[first].stack, "median")]
    report = replay_recording(path)
    assert report.ok, report.lines()
    assert report.profile_changes == 1 and report.stacks_matched == report.stacks_compared >= 7


def test_rotated_files_after_a_live_change_replay_on_their_own(tmp_path):
    """With rotation every file opens with the profile in use when it opened (it opened with the
    starting one, so each file after a change failed replay on its own)."""
    from edge.io.mcap import RecordingReader
    from edge.io.replay import replay_recording

    results, files = _record_with_a_live_change(tmp_path / "rot.mcap", {"decoder": {"method": "median"}},
                                                min_files=3, max_bytes=1_500_000)
    assert len(files) >= 3, files
    stored = [RecordingReader(f).profile.decoder.method for f in files]
    assert stored[0] == "soft" and stored[-1] == "median", stored
    compared = 0
    for f in files:
        report = replay_recording(f)
        assert not report.mismatches and not report.problem, report.lines()
        compared += report.stacks_compared
    assert compared >= 6


def test_an_older_recording_with_a_live_change_says_why_it_differs(tmp_path, monkeypatch):
    """A recording whose stacks do not carry the changed profile (made before they did) replays
    with the starting profile; its mismatches come with the reason."""
    from edge.io.recording import RecordingThread
    from edge.io.replay import replay_recording

    monkeypatch.setattr(RecordingThread, "_profile_change", lambda self, rec, r: None)
    path = tmp_path / "old.mcap"
    _record_with_a_live_change(path, {"decoder": {"method": "median", "max_error": 0.02}})
    report = replay_recording(path)
    assert not report.ok and report.profile_changes == 0
    assert report.notes and "live config changes" in report.notes[0], report.lines()


def test_the_recorded_frame_tree_follows_a_live_baseline_change(tmp_path):
    """/tf was written once, when the file opened: a live geometry.baseline_m change left the
    projector frame at the old baseline while /calibration and the live sinks followed."""
    from edge.io.mcap import RecordingReader

    path = tmp_path / "tf.mcap"
    results, _ = _record_with_a_live_change(path, {"geometry": {"baseline_m": 0.123}})
    tfs = [m for m in RecordingReader(path).messages() if m.topic.endswith("/tf")]
    xs = [max(abs(t.translation.x) for t in m.value.transforms) for m in tfs]
    assert len(tfs) == 2 and xs[1] == pytest.approx(0.123) and xs[0] == pytest.approx(results[0].profile.geometry.baseline_m)
    first_new = next(r for r in results if r.profile.geometry.baseline_m == 0.123)
    assert tfs[1].log_time == first_new.timestamp_ns


def test_an_event_recording_with_a_live_change_replays_bit_for_bit(tmp_path):
    """The event-recording replay read no stack message, so it decoded every stack with the
    starting profile (5 of 10 differed after a live baseline change)."""
    from _service_helpers import small_event_profile
    from edge.io.replay import replay_recording

    path = tmp_path / "events.mcap"
    results, _ = _record_with_a_live_change(path, {"geometry": {"baseline_m": 0.07}}, small_event_profile())
    assert len({r.profile.geometry.baseline_m for r in results}) == 2
    report = replay_recording(path)
    assert report.ok and report.profile_changes == 1, report.lines()


"""The service writes ``/<device>/stack`` (one JSON message per decoded stack) and replay stays bit-exact."""

from __future__ import annotations

from tests._service_helpers import load_test_profile

from edge.io.mcap import RecordingReader
from edge.io.recording import RecordingThread
from edge.io.replay import replay_recording
from edge.runtime.service import Service
from edge.sensors.base import parse_projector_frame
from edge.sensors.sim import SimSensor


def test_service_writes_one_stack_message_per_depth_map(tmp_path):
    profile = load_test_profile(edc={"rounds": 1}, sim={"scene": "v-groove"})
    out = tmp_path / "run.mcap"
    sensor = SimSensor(profile, max_speed=True)
    rec = RecordingThread(out, profile, sensor_metadata=sensor.info.metadata)
    # queue 8: a simulator at full speed on a loaded machine must not drop a stack (the queue drops the oldest)
    status = Service(profile, sensor, recorder=rec, queue_capacity=8).run(stacks=2)
    assert status["stacks_decoded"] == 2
    reader = RecordingReader(out)
    stacks = [m.value for m in reader.messages(topics=["/test-small/stack"])]  # JSON -> dict
    outputs = list(reader.outputs())
    assert [s["stack"] for s in stacks] == [o.stack for o in outputs] and len(stacks) == 2
    raw = list(reader.frames())
    per_stack = len(sensor.info.schedule)
    for s, o in zip(stacks, outputs):
        assert s["sequence"] == o.sequence and s["frames"] == per_stack
        masked = [f for f in raw if f.stack == s["stack"] and parse_projector_frame(f.projector_frame).edc_round > 0]
        plain = [f for f in raw if f.stack == s["stack"] and parse_projector_frame(f.projector_frame).edc_round == 0]
        assert len(plain) == s["frames"] and len(masked) == s["extra_frames"]
        assert s["edc_rounds"] >= 1 and len(s["edc_round_ms"]) == s["edc_rounds"] and s["decode_ms"] > 0
    report = replay_recording(out)
    assert report.ok and report.stacks_matched == 2, report.lines()

"""Who may change the sensor: config writes are off unless the profile enables them, zenoh ACL
rules pass through from the profile (and are required beyond loopback), rejections never echo a
huge value and are all counted, accepted changes are in the status and the recording."""

from __future__ import annotations

import json
import socket
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _service_helpers import NumpyPipeline, load_test_profile  # noqa: E402
from edge.io.zenoh import MAX_REASON_CHARS, ConfigRejected, DepthSubscriber  # noqa: E402
from edge.profiles import ProfileError, apply_update  # noqa: E402


def _endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def _service(endpoint: str, tmp_path: Path, **zenoh):
    from edge.io.publish import ZenohSink
    from edge.io.recording import RecordingThread
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    profile = load_test_profile(zenoh={"listen": [endpoint], **zenoh})
    recorder = RecordingThread(tmp_path / "rec.mcap", profile)
    service = Service(profile, SimSensor(profile, poses=1), recorder=recorder, pipeline_factory=NumpyPipeline)
    service.sinks.append(ZenohSink(profile, service))
    return service


def _close(service) -> None:
    for s in service.sinks:
        s.close()
    service.recorder.close()


def test_writes_are_off_by_default_and_the_refusal_is_counted(tmp_path):
    endpoint = _endpoint()
    service = _service(endpoint, tmp_path)
    try:
        with DepthSubscriber("test-small", connect=[endpoint]) as sub:
            assert sub.get_config()["decoder"]["method"] == "soft"     # reads always work
            with pytest.raises(ConfigRejected, match="config writes are off.*config_writes = true"):
                sub.update_config({"decoder": {"method": "hard"}})
            replies = list(sub.session.get("sl/test-small/config?decoder.method=hard", timeout=2.0))
            assert replies and replies[0].err is not None
        assert service.profile.decoder.method == "soft"
        assert service.status()["config_rejected"] == 2 and service.status()["config_updates"] == 0
    finally:
        _close(service)


def test_zenoh_layer_rejections_are_counted_and_huge_values_not_echoed(tmp_path):
    endpoint = _endpoint()
    service = _service(endpoint, tmp_path, config_writes=True)
    try:
        with DepthSubscriber("test-small", connect=[endpoint]) as sub:
            huge = "x" * 5_000_000
            for update in (b"not json", {"zenoh": {"status_period_s": 2.0}},              # zenoh layer
                           json.dumps({"decoder": {"method": huge}}).encode(),            # too large
                           {"decoder": {"method": "y" * 60_000}},                         # runtime, long
                           {"decoder": {"min_confidence": "high"}}):                      # runtime
                with pytest.raises(ConfigRejected) as info:
                    sub.update_config(update, timeout=10.0)
                text = str(info.value)
                assert "\n" not in text and len(text) <= MAX_REASON_CHARS + 80, len(text)
            assert service.status()["config_rejected"] == 5
            assert service.profile == load_test_profile(zenoh={"listen": [endpoint], "config_writes": True})
            before_ns = service.status()["last_config_change"]
            assert before_ns is None
            new = sub.update_config({"decoder": {"method": "hard", "min_confidence": 0.5}})
            assert new["decoder"]["method"] == "hard"
        change = service.status()["last_config_change"]
        assert change["keys"] == ["decoder.method", "decoder.min_confidence"] and change["time_ns"] > 0
    finally:
        _close(service)
    from edge.io.mcap import RecordingReader

    logged = [m.value for m in RecordingReader(tmp_path / "rec.mcap").messages()
              if m.topic == "/test-small/config_change"]
    assert len(logged) == 1 and logged[0]["keys"] == change["keys"]
    assert logged[0]["update"] == {"decoder": {"method": "hard", "min_confidence": 0.5}}
    assert logged[0]["profile"]["decoder"]["method"] == "hard"


def test_writes_beyond_loopback_need_acl_rules():
    with pytest.raises(ProfileError, match=r"zenoh\.config_writes: expected zenoh\.access_control rules.*0\.0\.0\.0"):
        load_test_profile(zenoh={"listen": ["tcp/0.0.0.0:7450"], "config_writes": True})
    with pytest.raises(ProfileError, match=r"zenoh\.config_writes: .*multicast scouting"):
        load_test_profile(zenoh={"multicast_scouting": True, "config_writes": True})
    with pytest.raises(ProfileError, match=r"zenoh\.access_control: zenoh rejects the ACL config"):
        load_test_profile(zenoh={"access_control": '{"enabled": 5}'})
    with pytest.raises(ProfileError, match=r"zenoh\.access_control: expected the JSON object"):
        load_test_profile(zenoh={"access_control": "[1, 2]"})
    load_test_profile(zenoh={"listen": ["tcp/0.0.0.0:7450"], "config_writes": False})  # reads only: fine
    load_test_profile(zenoh={"listen": ["tcp/0.0.0.0:7450"], "config_writes": True,
                             "access_control": json.dumps(_acl_denying_config_on("lo"))})


def _acl_denying_config_on(interface: str) -> dict:
    return {"enabled": True, "default_permission": "allow",
            "rules": [{"id": "no-config-writes", "permission": "deny", "flows": ["ingress"],
                       "messages": ["query"], "key_exprs": ["sl/test-small/config"]}],
            "subjects": [{"id": "untrusted", "interfaces": [interface]}],
            "policies": [{"rules": ["no-config-writes"], "subjects": ["untrusted"]}]}


def test_acl_rules_from_the_profile_reach_the_zenoh_session(tmp_path):
    """The documented ACL (deny queries on the config key from an interface) really applies: here
    on loopback, so the query never reaches the queryable, while depth still flows."""
    endpoint = _endpoint()
    profile = load_test_profile(zenoh={"listen": [endpoint], "config_writes": True,
                                       "access_control": json.dumps(_acl_denying_config_on("lo"))})
    from edge.io.zenoh import DepthPublisher

    pub = DepthPublisher(profile)
    try:
        with DepthSubscriber("test-small", connect=[endpoint]) as sub:
            with pytest.raises(ConfigRejected, match="no reply"):
                sub.update_config({"decoder": {"method": "hard"}}, timeout=1.0)
            assert pub.profile.decoder.method == "soft"
    finally:
        pub.close()
    assert apply_update(profile, {"decoder": {"method": "hard"}}).zenoh.access_control == profile.zenoh.access_control

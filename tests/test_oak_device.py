"""OAK backend, device side, without a device: the emitter Script node's program (run here with
stand-ins for depthai's on-device ``node`` / ``Device`` globals), device status and calibration
through a host pipeline whose default device is a stand-in, the [oak] profile table, live
``oak`` updates, and the service applying a sensor's own calibration to depth and status."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest

import depthai as dai  # noqa: E402

from _service_helpers import NumpyPipeline, load_test_profile  # noqa: E402
from test_sensors_oak import FakeMono, _oak_profile, read_frames  # noqa: E402

from edge.profiles import apply_update  # noqa: E402
from edge.sensors.base import parse_projector_frame, stack_schedule  # noqa: E402
from edge.sensors.oak import EmitterSchedule, OakSensor, config_buffer, emitter_script  # noqa: E402


class _Queue:
    def __init__(self, items):
        self.items = list(items)

    def get(self):
        if not self.items:
            raise StopIteration  # ends the script's endless loop
        return self.items.pop(0)

    def tryGet(self):  # noqa: N802 (depthai name)
        return self.items.pop(0) if self.items else None


class _Device:
    """Stand-in for the device global of a Script node: records the emitter calls."""

    def __init__(self):
        self.calls = []

    def setIrLaserDotProjectorIntensity(self, v):  # noqa: N802
        self.calls.append(("dot", v))

    def setIrFloodLightIntensity(self, v):  # noqa: N802
        self.calls.append(("flood", v))


def _run_script(emitters, seqs, configs=()):
    frames = [SimpleNamespace(getSequenceNum=lambda s=s: s) for s in seqs]
    node = SimpleNamespace(io={"frame": _Queue(frames), "config": _Queue(configs)})
    device = _Device()
    with pytest.raises(StopIteration):
        exec(compile(emitter_script(emitters), "edge-emitters", "exec"), {"node": node, "Device": device})
    return device.calls


def test_emitter_script_sets_the_next_frames_emitters_on_the_device():
    sched = stack_schedule(2, 4)  # 16 positions
    e = EmitterSchedule(sched, "1101", dot_intensity=0.5, flood_intensity=0.3, lead_frames=2)
    dot, flood = e.table()
    assert len(dot) == len(sched) and dot == [e.intensities(p)[0] for p in range(len(sched))]
    seqs = list(range(40, 60))
    calls = _run_script(e, seqs)
    # replay the expected command stream: one (dot, flood) pair whenever the wanted pair changes
    want, last = [], None
    for s in seqs:
        pair = (dot[(s + 2) % 16], flood[(s + 2) % 16])
        if pair != last:
            want += [("dot", pair[0]), ("flood", pair[1])]
            last = pair
    assert [(k, pytest.approx(v)) for k, v in calls] == want
    # a config message switches to a new table (here: lead 0, dots 0.9)
    e2 = EmitterSchedule(sched, "1101", dot_intensity=0.9, flood_intensity=0.0, lead_frames=0)
    msg = config_buffer(e2)
    calls = _run_script(e, [16], configs=[SimpleNamespace(getData=lambda: msg.getData())])
    assert calls == [("dot", 0.9), ("flood", 0.0)]  # position 0 of the new table


class _Calls:
    def __init__(self, value):
        self.average = value


class FakeDevice:
    """Stand-in for `dai.Device` with the calls the backend makes (values are made up)."""

    def __init__(self, calib):
        self.calib = calib
        self.commands = []

    def getDeviceId(self):  # noqa: N802
        return "18443010A1B2C3D400"

    def readCalibration(self):  # noqa: N802
        return self.calib

    def getProductName(self):  # noqa: N802
        return "OAK-D-PRO"

    def getBootloaderVersion(self):  # noqa: N802
        return "0.0.28"

    def getUsbSpeed(self):  # noqa: N802
        return dai.UsbSpeed.SUPER

    def getChipTemperature(self):  # noqa: N802
        return _Calls(41.234)

    def getLeonCssCpuUsage(self):  # noqa: N802
        return _Calls(0.125)

    def getLeonMssCpuUsage(self):  # noqa: N802
        return _Calls(0.5)

    def setIrLaserDotProjectorIntensity(self, v, mask=-1):  # noqa: N802
        self.commands.append(("dot", v))
        return True

    def setIrFloodLightIntensity(self, v, mask=-1):  # noqa: N802
        self.commands.append(("flood", v))
        return True


class DevicePipeline:
    """A host-only depthai pipeline whose default device is a `FakeDevice`."""

    def __init__(self, device):
        self._p = dai.Pipeline(createImplicitDevice=False)
        self._device = device

    def getDefaultDevice(self):  # noqa: N802
        return self._device

    def __getattr__(self, name):
        return getattr(self._p, name)


def _calibration():
    S = dai.CameraBoardSocket
    calib = dai.CalibrationHandler()
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    calib.setCameraIntrinsics(S.CAM_B, [[800.0, 0, 640], [0, 800.0, 400], [0, 0, 1]], 1280, 800)
    calib.setCameraIntrinsics(S.CAM_C, [[790.0, 0, 630], [0, 790.0, 405], [0, 0, 1]], 1280, 800)
    calib.setCameraExtrinsics(S.CAM_B, S.CAM_C, eye, [-7.5, 0.0, 0.0], [-7.5, 0.0, 0.0])
    return calib


def test_oak_settings_come_from_the_profile_and_device_status_reports_diagnostics(monkeypatch):
    profile = apply_update(_oak_profile(), {"oak": {"dot_intensity": 0.4, "flood_intensity": 0.2,
                                                     "lead_frames": 3, "emitter_control": "script"}})
    seqs = list(range(7, 17))
    FakeMono.sequences = seqs
    device = FakeDevice(_calibration())
    made = {}

    def fake_script_node(pipeline, tick, emitters):  # a Script node needs a device: record the wiring
        made.update(tick=tick, emitters=emitters)
        return None, SimpleNamespace(send=lambda buf: made.setdefault("sent", []).append(bytes(buf.getData())))

    monkeypatch.setattr("edge.sensors.oak.emitter_script_node", fake_script_node)
    sensor = OakSensor(profile, pipeline=DevicePipeline(device), output_factory=lambda p: p.create(FakeMono).out,
                       max_frames=len(seqs))
    assert (sensor.emitters.dot_intensity, sensor.emitters.flood_intensity, sensor.emitters.lead_frames) == (0.4, 0.2, 3)
    sensor.start()
    try:
        frames = read_frames(sensor, len(seqs))
        status = sensor.device_status()
        sensor.apply_settings(apply_update(profile, {"oak": {"dot_intensity": 0.7}}).oak)
    finally:
        sensor.stop()
    assert sensor.emitters_on_device and made["emitters"].lead_frames == 3
    # absolute numbering on the device's schedule: position = seq % frames_per_stack (5 here)
    assert [parse_projector_frame(f.projector_frame).base for f in frames[:3]] == [
        sensor.info.schedule[s % 5] for s in seqs[:3]]
    assert [f.stack for f in frames] == [s // 5 for s in seqs]
    # no host emitter calls while the device switches them; off at stop
    assert device.commands == [("dot", 0.0), ("flood", 0.0)]
    assert made["sent"] and made["sent"][0].decode().split(";")[0].split(",")[0] == "0.7"
    assert status["serial"] == "18443010A1B2C3D400" and status["product"] == "OAK-D-PRO"
    assert status["usb_speed"] == "SUPER" and status["temperature_c"] == 41.23
    assert status["cpu_css_percent"] == 12.5 and status["cpu_mss_percent"] == 50.0
    assert status["dot_intensity"] == 0.4 and status["emitter_control"] == "device script"
    assert status["depthai_version"] == dai.__version__
    with pytest.raises(ValueError, match="emitter_control"):
        sensor.apply_settings(apply_update(profile, {"oak": {"emitter_control": "host"}}).oak)


class _CalibratedSim:
    """A sim sensor that reports its own calibration (as OakSensor does after start)."""

    def __init__(self, profile, geometry):
        from edge.sensors.sim import SimSensor

        self._s = SimSensor(profile, poses=2, max_speed=True)
        self.device_geometry = geometry
        self.applied = []

    def apply_settings(self, oak):
        self.applied.append(oak)

    def __getattr__(self, name):
        return getattr(self._s, name)


def test_service_applies_the_sensor_calibration_and_reports_camera_status():
    from edge.runtime.service import Service

    profile = load_test_profile()
    g = profile.geometry
    device = {"baseline_m": 0.09, "focal_px": g.focal_px * 1.05, "cx_camera": g.cx_camera + 1.0,
              "cx_projector": g.cx_projector, "cy": g.cy - 1.0}
    sensor = _CalibratedSim(profile, device)
    results = []
    sink = SimpleNamespace(on_result=results.append, on_status=lambda s: None, close=lambda: None)
    service = Service(profile, sensor, sinks=[sink], pipeline_factory=NumpyPipeline)
    status = service.run(stacks=2)
    assert service.profile.geometry.focal_px == pytest.approx(device["focal_px"])
    assert all(r.geometry.baseline_m == 0.09 for r in results)
    intr = status["intrinsics"]
    assert intr["source"] == "device calibration" and intr["fx"] == pytest.approx(device["focal_px"])
    assert (intr["cx"], intr["cy"], intr["width"], intr["height"]) == (g.cx_camera + 1.0, g.cy - 1.0, 160, 120)
    assert status["edge_version"] and status["exposure_us"] > 0 and "projector_power" in status
    assert "gain" in status and "serial" in status and "firmware" in status
    # depth uses the device geometry: Z = f B / (d + doffs) with the new f and B
    r = results[-1]
    col = r.column
    ok = (col >= 0) & (r.depth_mm > 0)
    d = np.arange(col.shape[1])[None, :] - col
    z = device["focal_px"] * 0.09 * 1000 / (d + device["cx_projector"] - device["cx_camera"])
    assert np.allclose(r.depth_mm[ok], np.rint(z[ok]), atol=1)
    # a live oak update reaches the sensor; the sim has none to set
    new = service.update_config({"oak": {"dot_intensity": 0.3}})
    assert new.oak.dot_intensity == 0.3 and sensor.applied[-1].dot_intensity == 0.3
    from edge.sensors.sim import SimSensor

    plain = Service(profile, SimSensor(profile, poses=1, max_speed=True), pipeline_factory=NumpyPipeline)
    with pytest.raises(ValueError, match="no OAK emitters"):
        plain.update_config({"oak": {"dot_intensity": 0.3}})

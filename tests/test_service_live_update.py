"""A live config update changes the depth the service publishes once the decode thread swaps the pipeline."""

from __future__ import annotations

import numpy as np

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

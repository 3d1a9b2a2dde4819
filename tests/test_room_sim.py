"""Room simulator and joint matched filter: one process, several devices; `edge run --room` per kind."""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes.source_room import room_family
from edge.source.joint import design, foreign_columns, joint_despread
from edge.source.room_slots import SlotScenario, evaluate
from _ports import free_port


def test_foreign_columns_are_overlap_weighted_and_design_is_full_rank():
    fam = room_family(3, 8)
    cols = foreign_columns(fam[1], 16, 2.5)
    # every foreign "on" chip lands in my slots with total weight 1 (inside the window)
    assert cols.sum() == pytest.approx(fam[1].weight * 16 / 8, abs=fam[1].weight)
    assert np.all((cols >= 0) & (cols <= 1 + 1e-12))
    X = design(fam[0], fam[1:], [2.5, 6.25], 24)
    assert np.linalg.matrix_rank(X) == X.shape[1]
    fam5 = room_family(5, 8)
    with pytest.raises(ValueError, match="unknowns"):  # one symbol cannot hold four foreign devices
        joint_despread(np.zeros((8, 1, 4)), fam5[0], fam5[1:], offsets=[0.5, 1.5, 2.5, 3.5])


def test_joint_filter_refuses_offsets_that_do_not_match_the_foreign_codes():
    # zip() paired them silently: a foreign device without an offset was left out of the model
    fam = room_family(3, 8)
    slots = np.random.default_rng(0).random((16, 1, 4))
    for offsets in ([], [1.5], [1.5, 2.5, 3.5]):
        with pytest.raises(ValueError, match="2 foreign codes need 2 offsets"):
            joint_despread(slots, fam[0], fam[1:], offsets=offsets)
        with pytest.raises(ValueError, match="2 foreign codes need 2 offsets"):
            design(fam[0], fam[1:], offsets, 2)

@pytest.mark.parametrize("n", [2, 4])
def test_joint_filter_keeps_own_signal_under_overlap(n):
    """Item 2 figures: N <= 4, every foreign device at most as bright as the own one, fractional offsets,
    +-1e-3 drift, noise: own signal kept >= 95 %, false detections <= 0.5 %; the plain filter loses more."""
    r = evaluate(SlotScenario(n, pixels=600, seed=1), room_family(4, 8))
    assert r["joint"]["own_kept"] >= 0.95 and r["joint"]["false"] <= 0.005, r
    assert r["matched"]["own_kept"] < r["joint"]["own_kept"]
    assert r["uncoded"]["false"] > 0.005  # without codes foreign light is taken for own light


def test_dlp_room_depth_matches_alone_with_the_joint_filter():
    """Three source-coded DLP devices (small test profile) in one simulated room, one process."""
    from _service_helpers import TEST_PROFILE
    from edge.profiles import apply_update, load_profile
    from edge.runtime.assembly import StackAssembler
    from edge.runtime.pipelines import make_pipeline
    from edge.runtime.room import Member, room_family_for, room_profile
    from edge.sensors import open_sensor
    from edge.sensors.room_model import StaticMember, StaticRoom

    base = apply_update(load_profile(TEST_PROFILE), {"room": {"name": "lab", "family_size": 3}})
    members = [StaticMember(f"d{k}", k) for k in range(3)]
    prof = room_profile(base, Member("d1", 1, ""))
    fam = room_family_for(base)

    def depth(room, joint: bool):
        sensor = open_sensor(prof, "sim", room=room)
        pipe = make_pipeline(prof)
        if joint:
            pipe.foreign_sources = tuple(fam[m.code].string for m in room.members() if m.device != "d1")
        asm = StackAssembler(pipe.schedule)
        for pos, image in enumerate(sensor.render_stack(3)):
            st = asm.push(sensor._record(image, pos, 3, pos))
        return pipe.process(st).depth_mm

    alone = depth(StaticRoom("lab", members[1:2]), False)
    valid = alone > 0
    assert valid.mean() > 0.5
    for joint, lo in ((True, 0.95), (False, 0.0)):
        d = depth(StaticRoom("lab", members, 1), joint)
        agree = float(((np.abs(d.astype(int) - alone.astype(int)) <= 0.02 * alone) & valid).sum() / valid.sum())
        if joint:
            assert agree >= lo, agree
        else:
            plain = agree
    assert plain < 0.95  # the plain matched filter rejects symbols under overlap


@pytest.mark.parametrize("profile", ["room-events.toml", "room-curtain.toml", "test-small.toml"])
def test_edge_run_room_works_for_each_source_coded_kind(profile, capsys):
    from _service_helpers import DATA
    from edge.cli import main

    rc = main(["run", "--profile", str(DATA / "profiles" / profile), "--room", "solo", "--stacks", "1",
               "--max-speed", "--quiet", "--listen", f"tcp/127.0.0.1:{free_port()}"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert "room 'solo'" in out and "code 0 (" in out, out


def test_room_needs_zenoh_and_a_possible_family(capsys):
    from _service_helpers import DATA
    from edge.cli import main

    path = str(DATA / "profiles" / "room-curtain.toml")
    assert main(["run", "--profile", path, "--room", "x", "--no-zenoh", "--stacks", "1"]) == 2
    assert "--room needs zenoh" in capsys.readouterr().err

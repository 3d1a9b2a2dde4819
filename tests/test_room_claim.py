"""Room code claim: pure rules (tie-break, capacity, names) and real zenoh sessions on loopback."""

from __future__ import annotations

import threading
import time

import pytest

from edge.runtime.room import Member, RoomFull, RoomNameTaken, parse_token, resolve, token_key

import zenoh  # a hard dependency: a broken install fails here, it is not skipped
from _ports import free_port


def test_rules_tie_break_capacity_and_names():
    a, b, c = "0a", "0b", "0c"
    # three members that started at the same instant all claimed code 0: only the smallest zid keeps it
    same = [Member("dev", 0, a), Member("dev", 0, b), Member("dev", 0, c)]
    assert resolve("r", a, "dev", same, 3, current=same[0]) == Member("dev", 0, a)
    mb = resolve("r", b, "dev", same, 3, current=same[1])
    assert mb.code == 1 and mb.device == "dev-2"
    # capacity: the largest zid is refused, naming the room and members
    with pytest.raises(RoomFull, match="room 'r' is full: its family has 2 codes"):
        resolve("r", c, "dev", [Member("dev", 0, a), Member("dev-2", 1, b)], 2)
    # a newcomer never takes a held code, even with a smaller zid; a freed code is reused
    assert resolve("r", "01", "x", [Member("y", 0, a), Member("z", 2, b)], 3).code == 1
    # explicit names are never renamed
    with pytest.raises(RoomNameTaken, match="device name 'cam' is already in room 'r'"):
        resolve("r", b, "cam", [Member("cam", 0, a)], 3, explicit=True)
    with pytest.raises(RoomNameTaken):  # a newcomer never displaces a running member, whatever the zids
        resolve("r", a, "cam", [Member("cam", 0, b)], 3, explicit=True)
    # two that declared the same explicit name at once: the smaller zid keeps it
    assert resolve("r", a, "cam", [Member("cam", 1, b)], 3, explicit=True, current=Member("cam", 0, a)).device == "cam"
    key = token_key("sl", "r", Member("cam-2", 3, "abc"))
    assert key == "sl/room/r/cam-2/3/abc" and parse_token(key, "sl", "r") == Member("cam-2", 3, "abc")
    for bad in ("sl/room/r/cam/x/abc", "sl/room/r/cam/1", "sl/room/other/cam/1/abc", "sl/room/r/c m/1/z",
                "sl/room/r/cam/1/abc/f x", "sl/room/r/cam/1/abc/f/g"):
        assert parse_token(bad, "sl", "r") is None


def test_members_of_another_code_family_are_refused():
    """A claim's token names the family its index is into; a member that indexes another family (another
    sensor kind, projector stream, family_size or code_length) is refused: the same index is another
    code to it, so two members could project one code and each would filter the others with the wrong
    codes.  A token without a family (an older member) is taken as this member's family."""
    from edge.profiles import apply_update, load_profile
    from edge.runtime.room import RoomFamilyMismatch, family_tag

    me = Member("cam", 2, "0b", "frame-aperiodic-4x8")
    key = token_key("sl", "r", me)
    assert key == "sl/room/r/cam/2/0b/frame-aperiodic-4x8" and parse_token(key, "sl", "r") == me
    assert resolve("r", "0c", "dev", [me], 4, family="frame-aperiodic-4x8") == Member("dev", 0, "0c", "frame-aperiodic-4x8")
    assert resolve("r", "0c", "dev", [Member("old", 0, "0a")], 4, family="frame-aperiodic-4x8").code == 1
    with pytest.raises(RoomFamilyMismatch, match=r"room 'r' holds members of another code family: cam \(frame-aperiodic-4x8\); "
                                                 r"this one is event-periodic-4x6"):
        resolve("r", "0c", "dev", [me], 4, family="event-periodic-4x6")
    oak, events = load_profile("oak-d-pro"), load_profile("event-dots")
    assert family_tag(oak) != family_tag(events)  # the two kinds index different families
    assert family_tag(apply_update(oak, {"room": {"code_length": 6}})) == "frame-periodic-4x6"


def _until(predicate, timeout: float) -> bool:
    """Poll ``predicate`` until it holds or ``timeout`` seconds pass (liveliness tokens take a
    moment to travel between sessions; a fixed sleep flakes on a loaded machine)."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def _session(listen, connect=()):
    from edge.io.zenoh import make_config

    return zenoh.open(make_config(listen=[listen], connect=list(connect)))


def test_claims_over_zenoh_distinct_full_and_freed():
    from edge.io.room import RoomClaim, room_members

    eps = [f"tcp/127.0.0.1:{free_port()}" for _ in range(4)]
    sessions = [_session(eps[0])] + [_session(eps[i], eps[:i]) for i in range(1, 4)]
    claims, errors = [], []
    try:
        claims = [RoomClaim(s, prefix="sl", room="lab", device="cam", capacity=3, settle_s=0.4) for s in sessions[:3]]
        threads = [threading.Thread(target=lambda c=c: c.join()) for c in claims]  # simultaneous start
        for t in threads:
            t.start()
        for t in threads:
            t.join(20)
        codes = sorted(c.me.code for c in claims)
        names = sorted(c.me.device for c in claims)
        assert codes == [0, 1, 2] and len(set(names)) == 3, (codes, names)
        assert _until(lambda: [m.code for m in room_members(sessions[3], "sl", "lab")] == [0, 1, 2], 10), \
            room_members(sessions[3], "sl", "lab")
        fourth = RoomClaim(sessions[3], prefix="sl", room="lab", device="cam", capacity=3, settle_s=0.4)
        with pytest.raises(RoomFull, match="room 'lab' is full.*cam"):
            fourth.join()
        fourth.close()
        changes = []
        claims[0].on_change = lambda me, members: changes.append(len(members))
        freed = claims[1].me.code
        claims[1].close()
        sessions[1].close()  # the member's process goes away
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and len(claims[0].members()) != 2:
            time.sleep(0.05)
        assert len(claims[0].members()) == 2 and changes and changes[-1] == 2
        again = RoomClaim(sessions[3], prefix="sl", room="lab", device="cam", capacity=3, settle_s=0.4)
        assert again.join().code == freed
        assert again.status()["code"] == freed and len(again.status()["members"]) == 3
        again.close()
    finally:
        for c in claims:
            c.close()
        for s in sessions:
            try:
                s.close()
            except Exception:
                pass


def test_running_member_moves_when_an_outranking_claim_appears():
    """A conflict seen while running (e.g. a healed network partition): the larger zid re-claims and
    tells the service (on_change); the new token replaces the old one."""
    from edge.io.room import RoomClaim, room_members

    eps = [f"tcp/127.0.0.1:{free_port()}" for _ in range(2)]
    a, b = _session(eps[0]), _session(eps[1], eps[:1])
    claim = RoomClaim(a, prefix="sl", room="lab", device="cam", capacity=3, settle_s=0.3)
    try:
        assert claim.join().code == 0
        changes = []
        claim.on_change = lambda me, members: changes.append(me.code)
        ghost = b.liveliness().declare_token("sl/room/lab/ghost/0/0")  # zid 0 outranks every session
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and claim.me.code == 0:
            time.sleep(0.05)
        assert claim.me.code == 1 and changes and changes[-1] == 1 and claim.claim_changes == 1
        def seen():
            return sorted((m.device, m.code) for m in room_members(b, "sl", "lab"))

        assert _until(lambda: seen() == [("cam", 1), ("ghost", 0)], 10), seen()  # the old token went
        ghost.undeclare()
    finally:
        claim.close()
        a.close()
        b.close()


def test_service_switch_profile_keeps_the_schedule():
    from _service_helpers import load_test_profile
    from edge.runtime.service import Service
    from edge.sensors.sim import SimSensor

    p = load_test_profile(code={"source": "00110101"})
    service = Service(p, SimSensor(p, stacks=1, max_speed=True))
    service.switch_profile(load_test_profile(code={"source": "00011001"}))
    assert service.profile.code.source == "00011001"
    with pytest.raises(ValueError, match="stack schedule"):
        service.switch_profile(load_test_profile(code={"source": "0011"}))

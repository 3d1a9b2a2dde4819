"""The room claim rules: which device name and which family code a member holds (pure, no zenoh).

A *room* is a set of devices that share light.  Each member holds one *claim*: a device name (its
zenoh key-space name ``<prefix>/<device>/...``) and a code index ``0 <= code < capacity`` into the
room's source-code family (`room_source_code`).  Members learn each other's claims from liveliness
tokens (`edge.io.room`); this module only decides, from a member's view of the others, what it holds.

Invariants (every member applies the same rules to the same view, so they converge):

1. **Ordering.**  Members are ordered by zenoh session id (`zid_order`), which is unique per process.
2. **Keep unless outranked.**  A member keeps its current device name (code) unless another member
   with a *smaller* zid holds the same name (code); the smaller zid always wins a tie, so of two
   members that started at the same instant and claimed the same code exactly one moves.
3. **Lowest free.**  A member without a claim, or that lost one, takes the lowest code index held
   by no other member it sees, and for a default (non-explicit) device name the first of
   ``base, base-2, base-3, ...`` used by no other member.  Codes of members that left (token gone)
   are free again.  A newcomer never takes a held code or explicit name, so a running member is
   never displaced by one that joins later.
4. **Capacity.**  When every code is held by others, `resolve` raises `RoomFull` naming the room and
   its members: a device beyond the family's capacity refuses to run.  An explicit device name
   (``--device``) held by a member with a smaller zid raises `RoomNameTaken` instead of renaming.
5. **One family.**  A code index means a code of one family (`family_tag`: sensor kind, projector
   stream, family size and code length); a member that sees another that indexes another family
   raises `RoomFamilyMismatch` (a member that names no family is taken as of this one).

With a stable view, members that rejoin at most N - 1 times settle in one round each: every move
goes to a code no other member held in the mover's view.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable, Sequence

from edge.codes.source_room import room_code_kind, room_family_for  # noqa: F401  (re-exported here)

#: A device-name key chunk (as `edge.profiles.settings.ZenohSettings.device`).
_CHUNK = re.compile(r"[A-Za-z0-9_-]+")


@dataclass(frozen=True, order=True)
class Member:
    """One member's claim: ``device`` key-space name, ``code`` family index, ``zid`` zenoh session id,
    ``family`` the tag of the family its index is into (`family_tag`; "" from a member that does
    not say, which is taken as this member's family)."""

    device: str
    code: int
    zid: str
    family: str = ""

    def as_dict(self) -> dict:
        return {"device": self.device, "code": self.code, "zid": self.zid, "family": self.family}


class RoomFull(ValueError):
    """Every code of the room's family is held by another member."""

    def __init__(self, room: str, capacity: int, members: Sequence[Member]):
        self.room, self.capacity, self.members = room, capacity, list(members)
        names = ", ".join(f"{m.device} (code {m.code})" for m in sorted(self.members, key=lambda m: m.code))
        super().__init__(f"room {room!r} is full: its family has {capacity} codes, held by {names}; "
                         f"stop a member or use a larger [room] family_size")


class RoomNameTaken(ValueError):
    """An explicit device name is already held in the room by a member that outranks this one."""

    def __init__(self, room: str, device: str, members: Sequence[Member]):
        self.room, self.device, self.members = room, device, list(members)
        names = ", ".join(m.device for m in self.members)
        super().__init__(f"device name {device!r} is already in room {room!r} (members: {names}); "
                         f"choose another --device NAME")


class RoomFamilyMismatch(ValueError):
    """Another member of the room indexes another code family: the same index would be another code
    to it (two members could project one code, and each would filter the others' light with the
    wrong codes)."""

    def __init__(self, room: str, family: str, members: Sequence[Member]):
        self.room, self.family, self.members = room, family, list(members)
        names = ", ".join(f"{m.device} ({m.family})" for m in self.members)
        super().__init__(f"room {room!r} holds members of another code family: {names}; this one is {family} "
                         f"(sensor kind - projector stream - [room] family_size x code_length): every member of "
                         f"a room needs the same")


def family_tag(profile) -> str:
    """The room family a profile indexes into, as a key chunk: ``<kind>-<stream>-<size>x<length>``
    (`room_code_kind`, ``[room] family_size`` and ``code_length``), e.g. ``frame-aperiodic-4x8``."""
    kind, stream = room_code_kind(profile)
    return f"{kind}-{stream}-{int(profile.room.family_size)}x{int(profile.room.code_length)}"


def zid_order(zid: str) -> tuple[int, str]:
    """Sort key of a zenoh session id (hex string): numeric, then textual."""
    try:
        return int(zid, 16), zid
    except ValueError:
        return (1 << 128), zid


def token_key(prefix: str, room: str, member: Member) -> str:
    """``<prefix>/room/<room>/<device>/<code>/<zid>/<family>``: the liveliness key of a claim (no
    ``/<family>`` for a member without a family tag)."""
    tail = f"/{member.family}" if member.family else ""
    return f"{prefix}/room/{room}/{member.device}/{member.code}/{member.zid}{tail}"


def room_selector(prefix: str, room: str) -> str:
    """Key expression matching every claim token of ``room``."""
    return f"{prefix}/room/{room}/**"


def parse_token(key: str, prefix: str, room: str) -> Member | None:
    """The `Member` of a claim token key, or None when the key is not one (ignored, never fatal)."""
    head = f"{prefix}/room/{room}/"
    if not key.startswith(head):
        return None
    parts = key[len(head):].split("/")
    if len(parts) not in (3, 4) or not _CHUNK.fullmatch(parts[0]) or not parts[1].isdigit() \
            or not all(_CHUNK.fullmatch(p) for p in parts[2:]):
        return None
    return Member(parts[0], int(parts[1]), parts[2], parts[3] if len(parts) == 4 else "")


def _outranks(other: Member, zid: str) -> bool:
    return zid_order(other.zid) < zid_order(zid)


def resolve(room: str, zid: str, base_device: str, others: Iterable[Member], capacity: int, *,
            current: Member | None = None, explicit: bool = False, family: str = "") -> Member:
    """The claim a member with session ``zid`` holds given the ``others`` it sees (module invariants).

    base_device: the requested device name; explicit: it came from ``--device`` (never renamed);
    current: the member's present claim (None before its first claim); family: the tag of its
    code family (`family_tag`).  Raises `RoomFull` / `RoomNameTaken`, and `RoomFamilyMismatch`
    where another member says it indexes another family.
    """
    if capacity < 1:
        raise ValueError(f"room capacity must be >= 1, got {capacity}")
    others = [m for m in others if m.zid != zid]
    strangers = [m for m in others if family and m.family and m.family != family]
    if strangers:
        raise RoomFamilyMismatch(room, family, strangers)
    # device name
    taken_names = {m.device for m in others}
    if current is not None and not any(m.device == current.device and _outranks(m, zid) for m in others):
        device = current.device
    elif explicit:
        # a newcomer never takes a held name; of two that declared it at once the smaller zid keeps it
        if any(m.device == base_device and (current is None or _outranks(m, zid)) for m in others):
            raise RoomNameTaken(room, base_device, others)
        device = base_device
    else:
        device = base_device
        k = 2
        while device in taken_names:
            device = f"{base_device}-{k}"
            k += 1
    # code
    if current is not None and 0 <= current.code < capacity and \
            not any(m.code == current.code and _outranks(m, zid) for m in others):
        return Member(device, current.code, zid, family)
    held = {m.code for m in others}
    for code in range(capacity):
        if code not in held:
            return Member(device, code, zid, family)
    raise RoomFull(room, capacity, others)


# -- the room's family and a member's profile -------------------------------------------------------

def room_profile(profile, member: Member):
    """``profile`` as the room member ``member``: its family code as ``code.source`` and its device
    name as ``zenoh.device``."""
    from edge.profiles import apply_update

    code = room_family_for(profile)[member.code]
    return apply_update(profile, {"code": {"source": code.string}, "zenoh": {"device": member.device}},
                        source=f"{profile.source} + room {profile.room.name!r} claim {member.code}")

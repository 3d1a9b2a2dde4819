"""The shared room model of the simulated sensors: what a simulated device sees of the others.

What is shared between the processes of a room is only the **claim table** (every member's device
name and code index, from the liveliness tokens of `edge.io.room`); everything else is derived from
it deterministically, identically in every process, by `RoomLight`:

* the room's family (`edge.codes.source_room.room_family_for`): member code index -> bit string;
* a **room clock**: device d's slot clock runs at ``1 + drift_d`` own slots per room slot and
  starts at phase ``phi_d`` (slots), both hashed from (room, d) (drift within +-50 ppm, phase
  fractional); the offset of device k seen by device me at my slot t is
  ``tau(t) = (phi_k - phi_me) + (drift_k - drift_me) * t`` (fractional, drifting);
* power and position: device k's light at my camera has ``power`` in [0.5, 1] x my own level
  (hashed from (room, me, k): "each foreign device at most as bright as the own one") and comes from
  an emitter at ``baseline_factor`` in [1.3, 2.2] x my baseline (hashed), so it lands elsewhere in
  my image than my own light.

So N separate ``edge run --room NAME --sensor sim`` processes render mutually consistent light
without exchanging images, and one process can render the same room for tests (`StaticRoom`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Sequence

#: drift range of the room clock (+- parts per million)
DRIFT_PPM = 50.0
#: clock phases are drawn in [0, PHASE_SPAN) slots
PHASE_SPAN = 4096.0


def _unit(*parts: str) -> float:
    """Deterministic number in [0, 1) from strings (sha256)."""
    h = hashlib.sha256("/".join(parts).encode()).digest()
    return int.from_bytes(h[:8], "little") / 2.0**64


@dataclass(frozen=True)
class ForeignDevice:
    """Another member as this device's camera sees it.

    code: its source-code bit string; offset_slots: its clock offset at my slot 0 (my slots,
    fractional); drift: relative slot-rate difference (its slot = my slot x (1 + drift));
    power: its light / my own light at the same surface; baseline_factor: its emitter's baseline
    over mine; seed: for its random pattern (dot projectors)."""

    device: str
    code: str
    offset_slots: float
    drift: float
    power: float
    baseline_factor: float
    seed: int

    def offset_at(self, t_slots: float) -> float:
        """Its clock offset (my slots) at my slot ``t_slots``."""
        return self.offset_slots + self.drift * t_slots


@dataclass(frozen=True)
class StaticMember:
    device: str
    code: int
    zid: str = ""


class StaticRoom:
    """A fixed claim table for one-process simulations: ``StaticRoom("lab", members, me_index)``.

    codes: optional bit string per device name overriding the family (e.g. every device uncoded,
    ``"1"``, for the comparisons of tools/eval_room.py)."""

    def __init__(self, room: str, members: Sequence[StaticMember], me: int = 0,
                 codes: dict[str, str] | None = None) -> None:
        self.room = room
        self._members = list(members)
        self.me = self._members[me]
        self.codes = dict(codes) if codes else None

    def members(self):
        return list(self._members)


class RoomLight:
    """Foreign devices of a room for one simulated member (see module docstring).

    profile: the member's profile ([room] family settings); room: an object with ``room`` (name),
    ``me`` and ``members()`` (each with ``device`` and ``code``): `edge.io.room.RoomClaim` or
    `StaticRoom`.
    """

    def __init__(self, profile, room) -> None:
        from edge.codes.source_room import room_family_for

        self.profile = profile
        self.room = room
        self.family = room_family_for(profile)

    def clock(self, device: str) -> tuple[float, float]:
        """(phase slots, drift) of ``device`` on the room clock."""
        name = str(self.room.room)
        phase = _unit(name, device, "phase") * PHASE_SPAN
        drift = (2 * _unit(name, device, "drift") - 1) * DRIFT_PPM * 1e-6
        return phase, drift

    def code_of(self, member) -> str:
        """A member's code bit string: the room's explicit codes if it has them, else its family code."""
        codes = getattr(self.room, "codes", None)
        if codes:
            return codes[member.device]
        return self.family[int(member.code) % len(self.family)].string

    def own_code(self) -> str:
        """My code's bit string (from my current claim)."""
        return self.code_of(self.room.me)

    def foreign(self) -> list[ForeignDevice]:
        """The other members as my camera sees them (sorted by device name)."""
        me = self.room.me
        name = str(self.room.room)
        phi_me, d_me = self.clock(me.device)
        out = []
        for m in sorted(self.room.members(), key=lambda m: m.device):
            if m.device == me.device:
                continue
            phi, d = self.clock(m.device)
            out.append(ForeignDevice(
                device=m.device, code=self.code_of(m),
                offset_slots=phi - phi_me, drift=d - d_me,
                power=0.5 + 0.5 * _unit(name, me.device, m.device, "power"),
                baseline_factor=1.3 + 0.9 * _unit(name, me.device, m.device, "baseline"),
                seed=int(_unit(name, m.device, "seed") * 2**31)))
        return out

"""Automatic code claim over zenoh: the members of a room find each other by liveliness tokens.

Key (one liveliness token per member, no payload; everything is in the key)::

    <prefix>/room/<room>/<device>/<code>/<zid>/<family>

``device`` is the member's key-space name (its depth is on ``<prefix>/<device>/depth``), ``code`` the
index of its source code in the room's family, ``zid`` its zenoh session id, ``family`` the tag of
that family (`edge.runtime.room.family_tag`; a member of another family is refused,
`RoomFamilyMismatch`).  The claim rules are in
`edge.runtime.room` (pure); this module applies them to the live view:

* `RoomClaim.join`: subscribe to ``<prefix>/room/<room>/**`` (liveliness, with history), wait
  ``settle_s`` for the view, claim (`resolve`), declare the token, wait ``settle_s`` again and
  re-claim while the view shows a conflict this member loses (two members that start at the same
  instant: the larger zid moves).  Raises `RoomFull` / `RoomNameTaken` / `RoomFamilyMismatch`
  (ValueError: exit 2 on the CLI) naming the room and its members.
* While running, every change of the view (a member joins, leaves, or a conflict appears) re-runs
  the rules; a changed claim re-declares the token and calls ``on_change(me, members)`` (the service
  applies it between stacks).  A member whose process dies loses its token when its session's
  transport closes, so its code is free for the next claim.
* `close` undeclares the token (the code is freed at once) and the subscriber.

Every callback runs on a zenoh thread; the view and the claim are guarded by one lock and
``on_change`` is called outside it.
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Iterable

import zenoh

from edge.runtime.room import (Member, RoomFamilyMismatch, RoomFull, RoomNameTaken, parse_token, resolve,
                               room_selector, token_key)

__all__ = ["RoomClaim", "RoomFamilyMismatch", "RoomFull", "RoomNameTaken", "room_members"]

#: Seconds `join_room` waits for a first peer / router link when connect endpoints are configured.
CONNECT_WAIT_S = 5.0
#: Rounds of re-claiming `join` tries before it gives up (each member moves at most N - 1 times).
MAX_JOIN_ROUNDS = 32


def room_members(session: zenoh.Session, prefix: str, room: str, *, timeout: float = 2.0) -> list[Member]:
    """The claims present in ``room`` now (a liveliness query), sorted by code."""
    out = []
    for reply in session.liveliness().get(room_selector(prefix, room), timeout=timeout):
        if reply.ok is not None:
            m = parse_token(str(reply.ok.key_expr), prefix, room)
            if m is not None:
                out.append(m)
    return sorted(set(out), key=lambda m: (m.code, m.device))


class RoomClaim:
    """This member's claim in a room (see module docstring).

    session: an open zenoh session (not closed here); prefix / room: the key space; device: the
    requested device name (``explicit``: from ``--device``, never renamed); capacity: codes in the
    family; family: its tag (`edge.runtime.room.family_tag`, carried in the token); settle_s: how long to wait for tokens to propagate; on_change(me, members): called when
    the claim or the membership changes after `join`; on_lost(error): called when a running member
    loses its code and no code is free.
    """

    def __init__(self, session: zenoh.Session, *, prefix: str, room: str, device: str, capacity: int,
                 explicit: bool = False, settle_s: float = 0.5, family: str = "",
                 on_change: Callable[[Member, list[Member]], None] | None = None,
                 on_lost: Callable[[Exception], None] | None = None) -> None:
        self.session = session
        self.prefix, self.room, self.base_device, self.explicit = prefix, room, device, bool(explicit)
        self.capacity = int(capacity)
        self.family = str(family)
        self.settle_s = float(settle_s)
        self.on_change = on_change
        self.on_lost = on_lost
        self.zid = str(session.info.zid())
        self._lock = threading.RLock()
        self._notified: tuple | None = None
        self._view: dict[str, Member] = {}
        self._me: Member | None = None
        self._token = None
        self._joined = False
        self._closed = False
        self.claim_changes = 0
        self._sub = session.liveliness().declare_subscriber(room_selector(prefix, room), self._on_token,
                                                            history=True)

    # -- view ---------------------------------------------------------------------------------
    def _on_token(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        m = parse_token(key, self.prefix, self.room)
        if m is None:
            return
        with self._lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                self._view.pop(key, None)
            else:
                self._view[key] = m
            running = self._joined and not self._closed
        if running:
            self._reclaim()

    def _others(self) -> list[Member]:
        return [m for m in self._view.values() if m.zid != self.zid]

    @property
    def me(self) -> Member:
        if self._me is None:
            raise ValueError(f"not a member of room {self.room!r} yet (call join first)")
        return self._me

    def members(self) -> list[Member]:
        """Every member this one sees, itself included, sorted by code."""
        with self._lock:
            ms = self._others() + ([self._me] if self._me is not None else [])
        return sorted(set(ms), key=lambda m: (m.code, m.device))

    def status(self) -> dict:
        """``room``, ``code`` (this member's family index), ``members`` for the service status."""
        me = self._me
        return {"room": self.room, "code": me.code if me is not None else None,
                "members": [m.as_dict() for m in self.members()], "room_capacity": self.capacity,
                "room_claim_changes": self.claim_changes}

    # -- claim --------------------------------------------------------------------------------
    def _declare(self, me: Member) -> None:
        old, self._token = self._token, self.session.liveliness().declare_token(
            token_key(self.prefix, self.room, me))
        if old is not None:
            old.undeclare()
        self._me = me

    def join(self) -> Member:
        """Claim a device name and a code (see module docstring); returns this member's claim."""
        time.sleep(self.settle_s)
        for _ in range(MAX_JOIN_ROUNDS):
            with self._lock:
                others = self._others()
            me = resolve(self.room, self.zid, self.base_device, others, self.capacity, current=self._me,
                         explicit=self.explicit, family=self.family)
            if me != self._me:
                self._declare(me)
                time.sleep(self.settle_s)
                continue
            with self._lock:
                stable = resolve(self.room, self.zid, self.base_device, self._others(), self.capacity,
                                 current=self._me, explicit=self.explicit, family=self.family) == self._me
                if stable:
                    self._joined = True
                    self._notified = (self._me, tuple(self.members()))
                    return self._me
        raise ValueError(f"room {self.room!r}: no stable claim after {MAX_JOIN_ROUNDS} rounds "
                         f"(members: {', '.join(m.device for m in self.members())})")

    def _reclaim(self) -> None:
        with self._lock:
            if self._closed:
                return
            before = self._me
            try:
                me = resolve(self.room, self.zid, self.base_device, self._others(), self.capacity,
                             current=before, explicit=self.explicit, family=self.family)
            except (RoomFull, RoomNameTaken, RoomFamilyMismatch) as exc:
                lost = exc
            else:
                lost = None
                if me != before:
                    self._declare(me)
                    self.claim_changes += 1
        if lost is not None:
            if self.on_lost is not None:
                self.on_lost(lost)
            return
        state = (self._me, tuple(self.members()))
        if self.on_change is not None and state != self._notified:
            self._notified = state
            self.on_change(self._me, list(state[1]))

    def close(self) -> None:
        """Leave the room: undeclare the token (frees the code) and the subscriber."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            token, self._token = self._token, None
        for entity in (token, self._sub):
            if entity is not None:
                try:
                    entity.undeclare()
                except Exception:
                    pass

    def __enter__(self) -> "RoomClaim":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def others_of(members: Iterable[Member], me: Member) -> list[Member]:
    """The members other than ``me``."""
    return [m for m in members if m.zid != me.zid]


def join_room(profile, *, explicit_device: bool = False):
    """Open a zenoh session from ``profile.zenoh``, join ``profile.room.name`` and claim a code.

    Returns ``(session, claim, member_profile)``: the member profile carries the claimed family
    code as ``code.source`` and the claimed device name (`edge.runtime.room.room_profile`).  On any
    error the session is closed and the error (RoomFull / RoomNameTaken / ValueError) raised.
    """
    from edge.io.zenoh import open_session
    from edge.runtime.room import family_tag, room_family_for, room_profile

    family = room_family_for(profile)  # fails early on an impossible family
    session = open_session(profile.zenoh)
    claim = None
    try:
        if profile.zenoh.connect:  # the view means nothing before the links to the peers are up
            deadline = time.monotonic() + CONNECT_WAIT_S
            while time.monotonic() < deadline and not list(session.info.peers_zid()) \
                    and not list(session.info.routers_zid()):
                time.sleep(0.05)
        claim = RoomClaim(session, prefix=profile.zenoh.prefix, room=profile.room.name,
                          device=profile.zenoh.device, capacity=len(family), explicit=explicit_device,
                          settle_s=profile.room.settle_s, family=family_tag(profile))
        me = claim.join()
        return session, claim, room_profile(profile, me)
    except BaseException:
        if claim is not None:
            claim.close()
        session.close()
        raise


class RoomLink:
    """A joined room wired into one service: ``edge run --room`` (a sink of the service, so the
    service's shutdown leaves the room).

    `attach` adds the room to the service's status (``room``, ``code``, ``members``), gives the
    pipeline the other members' codes (joint matched filter, where the pipeline has
    ``foreign_sources``) and applies later claim changes between stacks (`Service.switch_profile`);
    a member that loses its code with none free stops the service with the reason in status.
    `close` (called by the service's shutdown, last of its sinks) frees the code and closes the session.
    """

    def __init__(self, base_profile, *, explicit_device: bool = False) -> None:
        self.base = base_profile
        self.session, self.claim, self.profile = join_room(base_profile, explicit_device=explicit_device)
        self.service = None
        self._seen = (self.claim.me, tuple(self.claim.members()))

    def describe(self) -> str:
        me = self.claim.me
        return (f"room {self.claim.room!r}: device {me.device}, code {me.code} ({self.profile.code.source}), "
                f"members {', '.join(m.device for m in self.claim.members())}")

    def foreign_sources(self, me: Member, members) -> tuple[str, ...]:
        from edge.runtime.room import room_family_for

        family = room_family_for(self.base)
        return tuple(family[m.code].string for m in members if m.zid != me.zid and 0 <= m.code < len(family))

    def attach(self, service) -> None:
        self.service = service
        service.extra_status.append(self.claim.status)
        if hasattr(service.pipeline, "foreign_sources"):
            service.pipeline.foreign_sources = self.foreign_sources(self.claim.me, self.claim.members())
        # every pipeline the service builds from now on (a live config update, a warm variant) gets
        # the other members' codes too: a live update turned the joint filter off
        factory = service.pipeline_factory

        def with_room(profile):
            pipeline = factory(profile)
            if hasattr(pipeline, "foreign_sources"):
                me, members = self._seen
                pipeline.foreign_sources = self.foreign_sources(me, members)
            return pipeline

        service.pipeline_factory = with_room
        self.claim.on_change = self._on_change
        self.claim.on_lost = self._on_lost

    def _on_change(self, me: Member, members) -> None:
        from edge.runtime.room import room_profile

        if (me, tuple(members)) == self._seen or self.service is None:
            return
        self._seen = (me, tuple(members))
        # from the running profile: the live updates accepted so far stay (the start-up profile undid
        # them); read and applied under the service's config lock, so a concurrent update keeps the claim
        self.service.switch_profile(lambda running: room_profile(running, me))

    def _on_lost(self, exc: Exception) -> None:
        if self.service is not None:
            self.service.counters.last_error = f"room: {exc}"
            self.service.fault = self.service.counters.last_error  # exit 1 with the reason on stderr
            self.service.stop()

    # sink protocol: nothing per result / status; close leaves the room
    def on_result(self, result) -> None:
        pass

    def on_status(self, status) -> None:
        pass

    def close(self) -> None:
        self.claim.close()
        try:
            self.session.close()
        except Exception:
            pass

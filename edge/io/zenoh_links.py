"""Router connectivity of a zenoh session, for the service's status: reconnects and time cut off.

What zenoh does by itself (eclipse-zenoh 1.x, checked on 1.10 in ``tests/test_routers.py``):
when the transport to a router in ``connect/endpoints`` closes (router restarted, network gone),
the session keeps retrying that endpoint (``connect/retry``: 1 s, doubling up to 4 s by default)
in client and in peer mode, and once it is back, publishers, subscribers, queryables and
liveliness tokens are re-declared on the new transport without any help from the application.
A *client* fails ``zenoh.open`` at once when no endpoint answers (``connect/timeout_ms`` 0 and
``connect/exit_on_failure`` true are the client defaults); a *peer* opens anyway and connects when
the router appears.  While no router is connected, samples are dropped (zenoh does not buffer).

What edge adds (`RouterLinks`): it watches the session's transport events
(``session.info.declare_transport_events_listener``, or polls ``session.info.routers_zid()`` on
zenoh versions without it) and counts, for the ``zenoh`` object of the status:

``routers``                 routers connected now
``peers``                   peers connected now (subscribers connected directly, other services)
``connected``               at least one router connected (always true without connect endpoints)
``disconnects``             times the last router transport closed
``reconnects``              times a router came back after a disconnect
``disconnected_s``          seconds without any router (includes the current gap): for a client
                            from the session's start, for a peer once it had seen a router
``published_while_disconnected``  depth maps put while no router was connected (lost for every
                            subscriber behind a router)
"""

from __future__ import annotations

import threading
import time
from typing import Any

import zenoh

__all__ = ["RouterLinks"]


class RouterLinks:
    """Counts router connects/disconnects of ``session`` (see the module docstring).

    ``expect_router``: the session cannot work without a router (a client), so any time without
    one is a gap; otherwise (a peer) gaps count only after a first router was connected.
    """

    def __init__(self, session: zenoh.Session, *, expect_router: bool, clock=time.monotonic):
        self._session = session
        self._clock = clock
        self._expect = bool(expect_router)
        self._lock = threading.Lock()
        self._routers: set[str] = set()
        self._peers: set[str] = set()
        self._down_since: float | None = clock() if self._expect else None
        self._down_total = 0.0
        self._ever_up = False
        self.disconnects = 0
        self.reconnects = 0
        self.published_while_disconnected = 0
        self._listener = None
        self._closed = False
        declare = getattr(session.info, "declare_transport_events_listener", None)
        self._polling = declare is None  # older zenoh: poll in stats()
        if declare is not None:
            self._listener = declare(self._on_event, history=True)
        # the history events may arrive later on a zenoh thread: take the transports open now too
        self._poll()

    # -- events -----------------------------------------------------------------------------------

    def _on_event(self, event: Any) -> None:
        if self._closed:
            return
        transport = event.transport
        zid = str(transport.zid)
        is_router = transport.whatami == zenoh.WhatAmI.ROUTER
        opened = event.kind == zenoh.SampleKind.PUT
        with self._lock:
            target = self._routers if is_router else self._peers
            if opened:
                target.add(zid)
            else:
                target.discard(zid)
            if is_router:
                self._router_count_changed()

    def _router_count_changed(self) -> None:  # under the lock
        now = self._clock()
        if self._routers and self._down_since is not None:
            self._down_total += now - self._down_since
            self._down_since = None
            if self._ever_up:
                self.reconnects += 1
        if self._routers:
            self._ever_up = True
        elif self._down_since is None and (self._expect or self._ever_up):
            self._down_since = now
            self.disconnects += 1

    def _poll(self) -> None:
        if self._closed:  # counts are final once closed
            return
        try:
            routers = {str(z) for z in self._session.info.routers_zid()}
            peers = {str(z) for z in self._session.info.peers_zid()}
        except Exception:  # a closed session
            return
        with self._lock:
            if not self._polling:  # seeding: events follow; only add what is open now
                routers |= self._routers
                peers |= self._peers
            changed = routers != self._routers
            self._routers, self._peers = routers, peers
            if changed:
                self._router_count_changed()

    # -- queries ----------------------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        """At least one router is connected (True when no router is expected and none was seen)."""
        if self._polling:
            self._poll()
        with self._lock:
            return bool(self._routers) or not (self._expect or self._ever_up)

    def count_publish(self) -> None:
        """Call once per depth map put: counts the ones put while no router was connected."""
        if not self.connected:
            with self._lock:
                self.published_while_disconnected += 1

    def stats(self) -> dict[str, Any]:
        """The ``zenoh`` object of the status (keys in the module docstring)."""
        if self._polling:
            self._poll()
        with self._lock:
            down = self._down_total
            if self._down_since is not None:
                down += self._clock() - self._down_since
            return {
                "routers": len(self._routers),
                "peers": len(self._peers),
                "connected": bool(self._routers) or not (self._expect or self._ever_up),
                "disconnects": self.disconnects,
                "reconnects": self.reconnects,
                "disconnected_s": round(down, 3),
                "published_while_disconnected": self.published_while_disconnected,
            }

    def close(self) -> None:
        """Undeclare the transport-events listener (before the session closes); the counts stay."""
        with self._lock:
            self._closed = True
            if self._down_since is not None:  # freeze the gap
                self._down_total += self._clock() - self._down_since
                self._down_since = None
        if self._listener is not None:
            try:
                self._listener.undeclare()
            except Exception:
                pass
            self._listener = None

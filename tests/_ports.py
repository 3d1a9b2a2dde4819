"""A free TCP port on loopback, for the zenoh sessions and routers of the tests and tools/."""

from __future__ import annotations

import socket


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now (the OS picks it; the caller binds
    it soon after, as the tests' zenoh endpoints do)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]

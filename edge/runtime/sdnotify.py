"""systemd service notifications (``sd_notify``) without a dependency.

systemd starts a ``Type=notify`` unit with ``NOTIFY_SOCKET`` (a unix datagram socket path, or an
abstract socket when it starts with ``@``) and, with ``WatchdogSec=``, ``WATCHDOG_USEC`` (and
``WATCHDOG_PID``).  The service sends newline-separated ``KEY=value`` assignments:

* ``READY=1`` once warm-up is done and capture runs (systemd then considers the unit started);
* ``WATCHDOG=1`` from the decode loop at least every ``WATCHDOG_USEC / 2`` (a stuck decoder stops
  pinging and systemd restarts the unit);
* ``STOPPING=1`` when the service begins to stop; ``STATUS=...`` free text shown by ``systemctl status``.

Without ``NOTIFY_SOCKET`` every call is a no-op, so the service runs the same outside systemd.
"""

from __future__ import annotations

import os
import socket
import threading
import time
from typing import Mapping

__all__ = ["Notifier"]


class Notifier:
    """Sends sd_notify messages to ``socket_path`` (default: ``$NOTIFY_SOCKET``).

    ``watchdog_usec`` (default ``$WATCHDOG_USEC`` when ``$WATCHDOG_PID`` is unset or this process)
    enables `watchdog`; pings are rate-limited to one per ``watchdog_usec / 4``.  Send errors never
    raise: they are counted in ``errors`` (a service must not die because systemd went away).
    """

    def __init__(self, socket_path: str | None = None, *, watchdog_usec: int | None = None,
                 env: Mapping[str, str] | None = None) -> None:
        env = os.environ if env is None else env
        self.socket_path = socket_path if socket_path is not None else env.get("NOTIFY_SOCKET") or None
        if watchdog_usec is None:
            pid = env.get("WATCHDOG_PID")
            usec = env.get("WATCHDOG_USEC")
            if usec and (not pid or pid == str(os.getpid())):
                try:
                    watchdog_usec = int(usec)
                except ValueError:
                    watchdog_usec = None
        self.watchdog_usec = watchdog_usec if watchdog_usec and watchdog_usec > 0 else None
        self.sent: list[str] = []   # every message sent (for status / tests)
        self.errors = 0
        self._last_ping = 0.0
        self._lock = threading.Lock()
        self._sock: socket.socket | None = None

    @property
    def enabled(self) -> bool:
        return bool(self.socket_path)

    def _address(self) -> str | bytes:
        path = self.socket_path or ""
        return b"\0" + path[1:].encode() if path.startswith("@") else path

    def notify(self, **fields: str | int) -> bool:
        """Send ``KEY=value`` lines (``notify(READY=1, STATUS="running")``); False if not sent."""
        if not self.enabled:
            return False
        message = "\n".join(f"{k}={v}" for k, v in fields.items())
        with self._lock:
            try:
                if self._sock is None:
                    self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
                    self._sock.setblocking(False)
                self._sock.sendto(message.encode(), self._address())
            except OSError:
                self.errors += 1
                return False
            self.sent.append(message)
            return True

    def ready(self, status: str = "") -> bool:
        return self.notify(READY=1, **({"STATUS": status} if status else {}))

    def stopping(self, status: str = "") -> bool:
        return self.notify(STOPPING=1, **({"STATUS": status} if status else {}))

    def status(self, text: str) -> bool:
        return self.notify(STATUS=text)

    def watchdog(self) -> bool:
        """``WATCHDOG=1`` if the watchdog is on and the last ping is older than a quarter period."""
        if self.watchdog_usec is None or not self.enabled:
            return False
        now = time.monotonic()
        if now - self._last_ping < self.watchdog_usec / 4e6:
            return False
        self._last_ping = now
        return self.notify(WATCHDOG=1)

    def close(self) -> None:
        with self._lock:
            if self._sock is not None:
                self._sock.close()
                self._sock = None

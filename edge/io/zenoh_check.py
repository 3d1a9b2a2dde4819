"""Start-up checks of a profile's ``[zenoh]`` endpoints and one-line zenoh error messages.

zenoh reports set-up failures as a `zenoh.ZError` whose text carries Rust source locations
(``... at /root/.cargo/.../unicast.rs:338.``); `describe_zenoh_error` turns one into a single line
that names the endpoint and the cause.  `check_endpoints` rejects what zenoh would reject (or
accept silently) before a session is opened: duplicate or malformed endpoints, bad ports.
`unreachable` lists ``connect`` endpoints where nobody answers (zenoh keeps retrying those in
the background in peer mode, so the service only warns).
"""

from __future__ import annotations

import re
import socket

__all__ = ["check_endpoints", "describe_zenoh_error", "unreachable"]

_LOCATION = re.compile(r"\s+at\s+\S+\.rs:\d+\.?")
_TCPISH = ("tcp", "udp", "tls", "quic", "ws")


def _split(endpoint: str) -> tuple[str, str, int | None]:
    """``tcp/127.0.0.1:7451#...`` -> ("tcp", "127.0.0.1", 7451); port None when absent/non-numeric."""
    proto, _, rest = endpoint.partition("/")
    address = re.split(r"[?#]", rest, maxsplit=1)[0]
    host, sep, port = address.rpartition(":")
    if not sep:
        return proto, address, None
    try:
        return proto, host.strip("[]"), int(port)
    except ValueError:
        return proto, host.strip("[]"), None


def check_endpoints(settings) -> None:
    """ValueError naming the first bad endpoint of ``settings`` (a `ZenohSettings`)."""
    for kind in ("listen", "connect"):
        seen: set[str] = set()
        for endpoint in getattr(settings, kind):
            proto, host, port = _split(endpoint)
            if not proto or "/" not in endpoint or not host:
                raise ValueError(f"zenoh {kind} endpoint {endpoint!r}: expected <protocol>/<address>, "
                                 f"e.g. tcp/127.0.0.1:7451")
            if proto in _TCPISH:
                if port is None or not 0 <= port <= 65535 or (kind == "connect" and port == 0):
                    raise ValueError(f"zenoh {kind} endpoint {endpoint!r}: expected a port "
                                     f"{'1' if kind == 'connect' else '0'}..65535")
            key = endpoint.split("#")[0]
            if key in seen and not (kind == "listen" and port == 0):
                raise ValueError(f"zenoh {kind} endpoint {endpoint!r} is given twice")
            seen.add(key)
    if settings.mode == "client" and not settings.connect:
        raise ValueError("zenoh mode 'client' needs a router to connect to: expected --connect ENDPOINT "
                         "(or zenoh.connect in the profile), got none")


def describe_zenoh_error(exc: BaseException, settings=None) -> str:
    """One line for a zenoh set-up failure (Rust locations stripped, the cause in plain words)."""
    text = " ".join(_LOCATION.sub("", str(exc)).split())
    text = text.replace("[", "").replace("]", "").rstrip(". ")
    hints = []
    if "Address already in use" in text:
        hints.append("another process (another edge run?) already listens there; pick a free port with --listen")
    elif "Cannot assign requested address" in text:
        hints.append("that address is not one of this host's; listen on a local address")
    elif "Unable to connect" in text:
        hints.append("nobody answers there; start the router first or check the address")
    where = ""
    if settings is not None:
        where = f" (mode {settings.mode}, listen {list(settings.listen)}, connect {list(settings.connect)})"
    return f"cannot open the zenoh session{where}: {text}" + (f": {hints[0]}" if hints else "")


def unreachable(endpoints, timeout_s: float = 0.5) -> list[tuple[str, str]]:
    """[(endpoint, reason)] for tcp ``connect`` endpoints where a TCP connection fails."""
    out = []
    for endpoint in endpoints:
        proto, host, port = _split(endpoint)
        if proto != "tcp" or port is None:
            continue
        try:
            with socket.create_connection((host, port), timeout=timeout_s):
                pass
        except OSError as exc:
            out.append((endpoint, exc.strerror or str(exc)))
    return out

"""Every device under a key prefix, seen from one subscriber (``edge subscribe --all``).

`DeviceMonitor(session, prefix)` declares three wildcard subscriptions on ``session``:

* ``<prefix>/*/alive`` liveliness (with history): which devices run now, and which went away;
* ``<prefix>/*/status``: the latest status of each device (fps, latency, drops, router links);
* ``<prefix>/*/depth``: arrival time and header of every depth map (the payload is not copied),
  so the depth rate and the latency (arrival - ``timestamp_ns`` of the stack) are measured here,
  at the subscriber, not taken from the service.

`rows` returns one `DeviceRow` per device ever seen; `format_table` renders them.
"""

from __future__ import annotations

import json
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import zenoh

__all__ = ["DeviceMonitor", "DeviceRow", "format_table"]


@dataclass
class DeviceRow:
    """One device as seen by the monitor; None = not known (yet)."""

    device: str
    alive: bool
    depth_per_s: float                 # depth maps received per second over the window
    latency_ms_p50: float | None       # measured here: arrival - timestamp_ns, over the window
    latency_ms_max: float | None
    depth_total: int                   # depth maps received since the monitor started
    status_fps: float | None           # the service's own figures, from its last status
    status_latency_ms_p50: float | None
    status_dropped: int | None
    status_reconnects: int | None
    status_age_s: float | None         # seconds since the last status arrived

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


class _Device:
    def __init__(self) -> None:
        self.alive = False
        self.status: dict[str, Any] | None = None
        self.status_at = 0.0
        self.depth: deque[tuple[float, float]] = deque(maxlen=4096)  # (monotonic arrival, latency ms)
        self.depth_total = 0


class DeviceMonitor:
    """Liveliness, status and measured depth rate / latency of every ``<prefix>/<device>``."""

    def __init__(self, session: zenoh.Session, prefix: str = "sl", *, depth: bool = True):
        self.session, self.prefix = session, prefix
        self._lock = threading.Lock()
        self._devices: dict[str, _Device] = {}
        self.errors: list[str] = []
        self._closed = False
        self._started = time.monotonic()
        self._entities = [
            session.liveliness().declare_subscriber(f"{prefix}/*/alive", self._on_alive, history=True),
            session.declare_subscriber(f"{prefix}/*/status", self._on_status),
        ]
        if depth:
            self._entities.append(session.declare_subscriber(f"{prefix}/*/depth", self._on_depth))

    def _device(self, key: Any, leaf: str) -> _Device | None:
        key = str(key)
        head, tail = f"{self.prefix}/", f"/{leaf}"
        if not (key.startswith(head) and key.endswith(tail)):
            return None
        name = key[len(head):-len(tail)]
        with self._lock:
            return self._devices.setdefault(name, _Device())

    def _on_alive(self, sample: zenoh.Sample) -> None:
        dev = self._device(sample.key_expr, "alive")
        if dev is not None:
            dev.alive = sample.kind == zenoh.SampleKind.PUT

    def _on_status(self, sample: zenoh.Sample) -> None:
        dev = self._device(sample.key_expr, "status")
        if dev is None:
            return
        try:
            status = json.loads(sample.payload.to_bytes())
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            self.errors.append(f"{sample.key_expr}: status is not JSON ({exc})")
            return
        if isinstance(status, dict):
            dev.status, dev.status_at = status, time.monotonic()

    def _on_depth(self, sample: zenoh.Sample) -> None:
        received_ns, now = time.time_ns(), time.monotonic()
        dev = self._device(sample.key_expr, "depth")
        if dev is None:
            return
        try:
            stamp = int(json.loads(sample.attachment.to_bytes())["timestamp_ns"])
        except Exception as exc:  # no / bad header: count the map, no latency
            self.errors.append(f"{sample.key_expr}: bad depth header ({type(exc).__name__}: {exc})")
            stamp = None
        with self._lock:
            dev.depth.append((now, (received_ns - stamp) / 1e6 if stamp is not None else float("nan")))
            dev.depth_total += 1

    def rows(self, window_s: float = 5.0) -> list[DeviceRow]:
        """One row per device seen, sorted by name; rates and latency over the last ``window_s``
        (or since the monitor started, if that is shorter)."""
        now = time.monotonic()
        span = max(1e-3, min(window_s, now - self._started))
        out = []
        with self._lock:
            items = sorted(self._devices.items())
            for name, dev in items:
                recent = [lat for t, lat in dev.depth if now - t <= window_s]
                lats = sorted(x for x in recent if x == x)
                st = dev.status or {}
                z = st.get("zenoh") if isinstance(st.get("zenoh"), dict) else {}
                out.append(DeviceRow(
                    device=name, alive=dev.alive,
                    depth_per_s=len(recent) / span,
                    latency_ms_p50=lats[len(lats) // 2] if lats else None,
                    latency_ms_max=lats[-1] if lats else None,
                    depth_total=dev.depth_total,
                    status_fps=_num(st.get("fps")),
                    status_latency_ms_p50=_num(st.get("latency_ms_p50")),
                    status_dropped=_int(st.get("stacks_dropped")),
                    status_reconnects=_int(z.get("reconnects")),
                    status_age_s=round(now - dev.status_at, 1) if dev.status is not None else None))
        return out

    def close(self) -> None:
        """Undeclare the subscriptions (the session stays open)."""
        if self._closed:
            return
        self._closed = True
        for entity in self._entities:
            try:
                entity.undeclare()
            except Exception:
                pass

    def __enter__(self) -> "DeviceMonitor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _num(x: Any) -> float | None:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else None


def _int(x: Any) -> int | None:
    return int(x) if isinstance(x, int) and not isinstance(x, bool) else None


def _fmt(x: float | int | None, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def format_table(rows: list[DeviceRow]) -> list[str]:
    """Fixed-width text table of `DeviceMonitor.rows` (measured columns first, then the status)."""
    width = max([len("device")] + [len(r.device) for r in rows])
    head = (f"{'device':<{width}}  alive  depth/s  lat p50  lat max  received | "
            f"svc fps  svc lat  dropped  reconn  status age")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r.device:<{width}}  {'yes' if r.alive else 'NO':<5}  {r.depth_per_s:7.1f}  "
            f"{_fmt(r.latency_ms_p50, '7.1f'):>7}  {_fmt(r.latency_ms_max, '7.1f'):>7}  {r.depth_total:8d} | "
            f"{_fmt(r.status_fps, '7.2f'):>7}  {_fmt(r.status_latency_ms_p50, '7.1f'):>7}  "
            f"{_fmt(r.status_dropped, 'd'):>7}  {_fmt(r.status_reconnects, 'd'):>6}  "
            f"{_fmt(r.status_age_s, '.1f'):>9} s")
    if not rows:
        lines.append("(no device yet)")
    return lines

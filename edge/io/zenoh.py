"""The edge zenoh key space: `DepthPublisher` (service side) and `DepthSubscriber` (client side).

Keys (``<prefix>/<device>`` from the profile's ``[zenoh]`` table, e.g. ``sl/sim-dlp``):

``sl/<device>/depth``       payload: H*W uint16 little-endian millimetres, row-major, 0 = invalid
                            (ROS REP 118 16UC1); encoding ``application/octet-stream;16UC1``.
``sl/<device>/confidence``  payload: H*W uint8, higher = more confident; ``...;mono8``.
``sl/<device>/error``       payload: H*W float32 little-endian, the decoder's estimated probability
                            that the pixel's column (so its depth) is wrong, NaN where there is no
                            depth or no estimate; ``...;32FC1``.  Published with the depth maps
                            decoded under the error-probability rule (the default for column
                            codes), after depth and before confidence; absent otherwise.
``sl/<device>/status``      JSON object once per ``status_period_s``: whatever the runtime passes
                            (fps, latency_ms, stacks_dropped, edc_rounds, decoder, errors, ...)
                            plus ``device``, ``time_ns`` and ``zenoh`` (router links: reconnects,
                            disconnected_s, ...; `edge.io.zenoh_links`).
``sl/<device>/config``      queryable. ``get`` with no payload and no parameters -> the active
                            profile as JSON (`edge.profiles.profile_to_dict`). ``get`` with a JSON
                            object payload (a partial profile, e.g. ``{"decoder": {"method":
                            "hard"}}``) or with parameters (``sl/dev/config?edc.rounds=2``, values
                            parsed as JSON when they parse) -> validated update: the reply is the new
                            profile, or ``reply_err`` with ``config update rejected: <reason>``; on
                            any error the running profile is kept. ``zenoh.*`` and ``name`` cannot
                            change while running. Writes are refused unless the profile sets
                            ``[zenoh] config_writes = true`` (reads always work); beyond loopback
                            the profile must also carry zenoh ACL rules (``zenoh.access_control``).
                            Payloads over `MAX_CONFIG_BYTES` are refused unread; a rejection
                            message is one line of at most `MAX_REASON_CHARS` characters.
``sl/<device>/alive``       liveliness token, present while the publisher is open.
``sl/<device>/points``      the point cloud of each depth map (`DepthPublisher.publish_points`):
                            N*12 bytes, N points of float32 little-endian x y z in metres in the
                            camera optical frame (REP 103: x right, y down, z forward); header
                            ``{"v": 1, "encoding": "xyz32f", "units": "m", "count": N,
                            "frame_id", "timestamp_ns", "sequence", "stack", "published_ns"}``
                            (`decode_points`).

Header (the zenoh *attachment* of every depth, error and confidence sample): UTF-8 JSON object
``{"v": 1, "width": W, "height": H, "encoding": "16UC1" | "32FC1" | "mono8", "units": "mm" |
"probability" | "1/255", "error": true (depth samples followed by an error image only),
"timestamp_ns": <time of the stack's last camera frame>, "sequence": <depth-map counter>,
"stack": <stack id>, "published_ns": <wall clock at put>}``. Latency at a subscriber is
``time.time_ns() - timestamp_ns`` (timestamps are wall-clock ns, same host or synced clocks).

Five-line subscriber (see also `DepthSubscriber`)::

    import json, signal, zenoh, numpy as np
    conf = zenoh.Config(); conf.insert_json5("connect/endpoints", '["tcp/127.0.0.1:7451"]'); conf.insert_json5("scouting/multicast/enabled", "false")
    def on(sample): h = json.loads(sample.attachment.to_bytes()); d = np.frombuffer(sample.payload.to_bytes(), "<u2").reshape(h["height"], h["width"]); print(h["sequence"], d.max(), flush=True)
    stop = {signal.SIGINT, signal.SIGTERM}; signal.pthread_sigmask(signal.SIG_BLOCK, stop)
    with zenoh.open(conf) as s, s.declare_subscriber("sl/sim-dlp/depth", on): signal.sigwait(stop)
"""

from __future__ import annotations

import json
import queue
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping

import numpy as np
import zenoh

from edge.profiles import Profile, profile_to_dict
from edge.profiles.live import ConfigRejected, live_update
from edge.profiles.settings import ZenohSettings

from .zenoh_links import RouterLinks

__all__ = [
    "HEADER_VERSION",
    "ConfigRejected",
    "DepthPublisher",
    "DepthSubscriber",
    "DepthSample",
    "make_config",
    "open_session",
    "open_router",
    "encode_header",
    "decode_header",
    "decode_image",
    "get_config",
    "update_config",
    "is_alive",
    "decode_points",
    "PointsSample",
]

HEADER_VERSION = 1
#: Largest config-update payload (or parameter string) read, in bytes.
MAX_CONFIG_BYTES = 64 * 1024
#: Longest rejection reason sent back (the value that caused it is never echoed whole).
MAX_REASON_CHARS = 300
_DEPTH_ENCODING = zenoh.Encoding.APPLICATION_OCTET_STREAM.with_schema("16UC1")
_CONF_ENCODING = zenoh.Encoding.APPLICATION_OCTET_STREAM.with_schema("mono8")
_ERROR_ENCODING = zenoh.Encoding.APPLICATION_OCTET_STREAM.with_schema("32FC1")
_DTYPES = {"16UC1": np.dtype("<u2"), "mono8": np.dtype(np.uint8), "32FC1": np.dtype("<f4")}
_UNITS = {"16UC1": "mm", "mono8": "1/255", "32FC1": "probability"}


class _RuntimeRejected(Exception):
    """A rejection made by ``on_update`` (the runtime counts those itself)."""


def one_line(text: str, limit: int = MAX_REASON_CHARS) -> str:
    """``text`` on one line, cut to ``limit`` characters with the full length said."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else f"{line[:limit]}... ({len(line)} characters)"


# -- sessions ------------------------------------------------------------------------------------


def make_config(*, mode: str = "peer", listen: Iterable[str] = (), connect: Iterable[str] = (),
                multicast_scouting: bool = False, connect_timeout_s: float = 0.0,
                access_control: str = "") -> zenoh.Config:
    """A zenoh.Config with the mode, endpoints, multicast scouting and (if given) the JSON text of
    zenoh's ``access_control`` (ACL) object set (nothing else but, for a client with
    ``connect_timeout_s`` > 0, ``connect/timeout_ms``: how long ``zenoh.open`` waits for one of the
    ``connect`` routers before it fails)."""
    conf = zenoh.Config()
    if mode == "client" and connect_timeout_s > 0:
        conf.insert_json5("connect/timeout_ms", json.dumps(int(round(connect_timeout_s * 1000))))
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(bool(multicast_scouting)))
    if access_control:
        conf.insert_json5("access_control", access_control)
    return conf


def open_router(listen: Iterable[str], connect: Iterable[str] = (), *,
                multicast_scouting: bool = False) -> zenoh.Session:
    """An in-process zenoh *router* (what ``zenohd`` does; zenohd is not on PyPI): it listens on
    ``listen``, joins the routers in ``connect`` (a mesh; zenoh retries them while they are down)
    and routes between every client and peer connected to any router of the mesh.  Close it
    with ``close()``.  ``edge router`` runs one from the command line."""
    return zenoh.open(make_config(mode="router", listen=listen, connect=connect,
                                  multicast_scouting=multicast_scouting))


def open_session(settings: ZenohSettings) -> zenoh.Session:
    """A zenoh session configured from a profile's ``[zenoh]`` table."""
    return zenoh.open(make_config(mode=settings.mode, listen=settings.listen, connect=settings.connect,
                                  multicast_scouting=settings.multicast_scouting,
                                  connect_timeout_s=settings.connect_timeout_s,
                                  access_control=getattr(settings, "access_control", "")))


# -- header / payload ----------------------------------------------------------------------------


def encode_header(*, width: int, height: int, encoding: str, timestamp_ns: int, sequence: int,
                  stack: int = -1, error: bool = False) -> bytes:
    """The JSON attachment of a depth / error / confidence sample (see the module docstring);
    ``error``: the depth sample's ``"error": true`` (an error image with its sequence follows)."""
    units = _UNITS.get(encoding, "1/255")
    head = {"v": HEADER_VERSION, "width": int(width), "height": int(height), "encoding": encoding, "units": units,
            "timestamp_ns": int(timestamp_ns), "sequence": int(sequence), "stack": int(stack),
            "published_ns": time.time_ns()}
    if error:
        head["error"] = True
    return json.dumps(head).encode()


def _json_attachment(attachment: bytes | None, what: str) -> Any:
    """The parsed JSON of a sample's attachment; ValueError naming ``what`` if absent or not JSON."""
    if not attachment:
        raise ValueError(f"expected a JSON header attachment on the {what}, got none")
    try:
        return json.loads(attachment)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"expected a JSON {what} header, got undecodable bytes ({exc})") from None


def decode_header(attachment: bytes | None) -> dict[str, Any]:
    """Parse and check a sample header; ValueError with the reason if it is not one."""
    header = _json_attachment(attachment, "sample")
    if not isinstance(header, dict):
        raise ValueError(f"expected a JSON object as the sample header, got {type(header).__name__}")
    missing = [k for k in ("width", "height", "encoding", "timestamp_ns", "sequence") if k not in header]
    if missing:
        raise ValueError(f"expected header keys width, height, encoding, timestamp_ns, sequence; missing {missing}")
    if header["encoding"] not in _DTYPES:
        raise ValueError(f"expected header encoding in {sorted(_DTYPES)}, got {header['encoding']!r}")
    return header


def decode_image(payload: bytes, header: Mapping[str, Any]) -> np.ndarray:
    """(H, W) uint16 depth (mm), float32 error probability or uint8 confidence from a sample
    payload and its header."""
    dtype = _DTYPES[header["encoding"]]
    h, w = int(header["height"]), int(header["width"])
    if len(payload) != h * w * dtype.itemsize:
        raise ValueError(f"expected {h * w * dtype.itemsize} payload bytes for {w}x{h} "
                         f"{header['encoding']}, got {len(payload)}")
    return np.frombuffer(payload, dtype=dtype).reshape(h, w).astype(dtype.newbyteorder("="))


def decode_points(payload: bytes, attachment: bytes | None) -> tuple[np.ndarray, dict[str, Any]]:
    """((N, 3) float32 points in metres, header) of a ``sl/<device>/points`` sample."""
    header = _json_attachment(attachment, "points sample")
    if not isinstance(header, dict) or header.get("encoding") != "xyz32f" or not isinstance(header.get("count"), int):
        raise ValueError(f"expected a points header with encoding 'xyz32f' and an integer count, got {header!r}")
    n = header["count"]
    if len(payload) != 12 * n:
        raise ValueError(f"expected {12 * n} payload bytes for {n} xyz32f points, got {len(payload)}")
    return np.frombuffer(payload, dtype="<f4").reshape(n, 3).astype(np.float32), header


def _parameters_to_update(parameters: Any) -> dict[str, Any]:
    """``a.b=1;c.d=hard`` -> {"a": {"b": 1}, "c": {"d": "hard"}} (values JSON-parsed when possible)."""
    update: dict[str, Any] = {}
    for key, raw in dict(parameters).items():
        try:
            value = json.loads(raw)
        except json.JSONDecodeError:
            value = raw
        node = update
        parts = key.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ValueError(f"expected {part!r} to be a table in parameter {key!r}")
        node[parts[-1]] = value
    return update


# -- publisher -----------------------------------------------------------------------------------


class DepthPublisher:
    """Service side of the key space: publishers, config queryable and liveliness token.

    ``on_update(partial: dict) -> Profile`` applies a validated config update in the runtime
    (raise ValueError with a reason to reject it); by default `edge.profiles.live_update` (the
    service's config-freeze policy) is used and the new profile only stored here. It runs on a
    zenoh thread, serialised by a lock. ``session``: an existing session to use (not closed by
    `close`); default: one opened from ``profile.zenoh``.
    ``on_reject(reason)`` is called for every rejection made here, before ``on_update`` (writes
    disabled, a payload too large or not JSON); ``rejected`` counts them too.
    """

    def __init__(self, profile: Profile, *, on_update: Callable[[dict[str, Any]], Profile] | None = None,
                 session: zenoh.Session | None = None, on_reject: Callable[[str], None] | None = None):
        self._profile = profile
        self._on_update = on_update
        self._on_reject = on_reject
        self.rejected = 0
        self._lock = threading.Lock()
        self._closed = False
        z = profile.zenoh
        self.keys = {leaf: z.key(leaf) for leaf in ("depth", "error", "confidence", "status", "config", "alive",
                                                    "points")}
        self._own_session = session is None
        self.session = session if session is not None else open_session(z)
        try:
            # Not express: with express=True and the default DROP congestion control, zenoh 1.10
            # dropped back-to-back samples on loopback in our tests; batching keeps them.
            self._depth = self.session.declare_publisher(self.keys["depth"], encoding=_DEPTH_ENCODING)
            self._error = self.session.declare_publisher(self.keys["error"], encoding=_ERROR_ENCODING)
            self._confidence = self.session.declare_publisher(self.keys["confidence"], encoding=_CONF_ENCODING)
            self._status = self.session.declare_publisher(self.keys["status"],
                                                          encoding=zenoh.Encoding.APPLICATION_JSON)
            self._points = self.session.declare_publisher(self.keys["points"],
                                                          encoding=_DEPTH_ENCODING.with_schema("xyz32f"))
            self._queryable = self.session.declare_queryable(self.keys["config"], self._on_query)
            self._token = self.session.liveliness().declare_token(self.keys["alive"])
            self.links = RouterLinks(self.session, expect_router=z.mode == "client")
        except BaseException:
            if self._own_session:
                self.session.close()
            raise

    @property
    def profile(self) -> Profile:
        """The active profile (replaced by accepted config updates)."""
        return self._profile

    def publish_depth(self, depth_mm: np.ndarray, confidence: np.ndarray | None, *, timestamp_ns: int,
                      sequence: int, stack: int = -1, error: np.ndarray | None = None) -> None:
        """Publish one depth map (H, W) uint16 mm and, if given, its (H, W) float32 error
        probability (NaN = no estimate) and its (H, W) uint8 confidence, in that order."""
        depth_mm = np.asarray(depth_mm)
        if depth_mm.ndim != 2 or depth_mm.dtype != np.uint16:
            raise ValueError(f"expected depth as (H, W) uint16 mm, got {depth_mm.dtype} {depth_mm.shape}")
        h, w = depth_mm.shape
        if error is not None:
            error = np.asarray(error)
            if error.shape != depth_mm.shape or error.dtype != np.float32:
                raise ValueError(f"expected error as {depth_mm.shape} float32, got {error.dtype} {error.shape}")
        head = encode_header(width=w, height=h, encoding="16UC1", timestamp_ns=timestamp_ns,
                             sequence=sequence, stack=stack, error=error is not None)
        self._depth.put(np.ascontiguousarray(depth_mm, dtype="<u2").tobytes(), attachment=head)
        self.links.count_publish()
        if error is not None:
            head = encode_header(width=w, height=h, encoding="32FC1", timestamp_ns=timestamp_ns,
                                 sequence=sequence, stack=stack)
            self._error.put(np.ascontiguousarray(error, dtype="<f4").tobytes(), attachment=head)
        if confidence is not None:
            confidence = np.asarray(confidence)
            if confidence.shape != depth_mm.shape or confidence.dtype != np.uint8:
                raise ValueError(f"expected confidence as {depth_mm.shape} uint8, got {confidence.dtype} {confidence.shape}")
            head = encode_header(width=w, height=h, encoding="mono8", timestamp_ns=timestamp_ns,
                                 sequence=sequence, stack=stack)
            self._confidence.put(np.ascontiguousarray(confidence).tobytes(), attachment=head)

    def publish_points(self, xyz: np.ndarray, *, timestamp_ns: int, sequence: int, stack: int = -1,
                       frame_id: str = "") -> None:
        """Publish one point cloud: (N, 3) points in metres (stored float32 LE), see the module docstring."""
        xyz = np.asarray(xyz)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise ValueError(f"expected points as (N, 3), got {xyz.dtype} {xyz.shape}")
        head = json.dumps({"v": HEADER_VERSION, "encoding": "xyz32f", "units": "m", "count": int(xyz.shape[0]),
                           "frame_id": frame_id, "timestamp_ns": int(timestamp_ns), "sequence": int(sequence),
                           "stack": int(stack), "published_ns": time.time_ns()}).encode()
        self._points.put(np.ascontiguousarray(xyz, dtype="<f4").tobytes(), attachment=head)

    def publish_status(self, status: Mapping[str, Any]) -> None:
        """Publish a JSON status object (``device``, ``time_ns`` and ``zenoh``, the router links of
        `edge.io.zenoh_links.RouterLinks`, are added)."""
        body = {**dict(status), "device": self._profile.zenoh.device, "time_ns": time.time_ns(),
                "zenoh": self.links.stats()}
        self._status.put(json.dumps(body, default=str).encode())

    # -- config queryable ------------------------------------------------------------------------

    def _on_query(self, query: zenoh.Query) -> None:
        try:
            payload = query.payload.to_bytes() if query.payload is not None else b""
            params = dict(query.parameters) if query.parameters is not None else {}
            if not payload and not params:
                query.reply(self.keys["config"], json.dumps(profile_to_dict(self._profile)).encode(),
                            encoding=zenoh.Encoding.APPLICATION_JSON)
                return
            new = self._update(payload, params)
            query.reply(self.keys["config"], json.dumps(profile_to_dict(new)).encode(),
                        encoding=zenoh.Encoding.APPLICATION_JSON)
        except Exception as exc:  # every failure goes back to the caller, never kills the service
            reason = one_line(str(exc))
            if not isinstance(exc, _RuntimeRejected):
                self.rejected += 1
                if self._on_reject is not None:
                    try:
                        self._on_reject(reason)
                    except Exception:
                        pass
            try:
                query.reply_err(f"config update rejected: {reason}".encode(), encoding=zenoh.Encoding.TEXT_PLAIN)
            except Exception:
                pass

    def _update(self, payload: bytes, params: Mapping[str, str]) -> Profile:
        if not self._profile.zenoh.config_writes:
            raise ValueError(f"config writes are off on {self._profile.zenoh.device} (its profile must set "
                             f"[zenoh] config_writes = true; reads need no permission)")
        size = len(payload) + sum(len(k) + len(v) for k, v in params.items())
        if size > MAX_CONFIG_BYTES:
            raise ValueError(f"expected a config update of at most {MAX_CONFIG_BYTES} bytes, got {size}")
        if payload and params:
            raise ValueError("expected a JSON payload or parameters, got both")
        if payload:
            try:
                update = json.loads(payload)
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise ValueError(f"payload is not valid JSON ({exc})") from None
        else:
            update = _parameters_to_update(params)
        if not isinstance(update, dict):
            raise ValueError(f"expected a JSON object of settings, got {type(update).__name__}")
        with self._lock:
            if self._on_update is not None:
                try:
                    new = self._on_update(update)
                except Exception as exc:
                    raise _RuntimeRejected(str(exc)) from exc
                if not isinstance(new, Profile):
                    raise ValueError(f"on_update returned {type(new).__name__}, expected a Profile")
            else:  # the service's config-freeze policy (edge.profiles.live), without a service
                new, _ = live_update(self._profile, update, source=f"{self.keys['config']} update")
            self._profile = new
        return new

    # -- lifetime --------------------------------------------------------------------------------

    def close(self) -> None:
        """Undeclare the token, queryable and publishers, then close the session (if owned)."""
        if self._closed:
            return
        self._closed = True
        self.links.close()
        for entity in (self._token, self._queryable, self._points, self._status, self._confidence, self._error,
                       self._depth):
            try:
                entity.undeclare()
            except Exception:
                pass
        if self._own_session:
            self.session.close()

    def __enter__(self) -> "DepthPublisher":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


# -- client side ---------------------------------------------------------------------------------


@dataclass
class DepthSample:
    depth_mm: np.ndarray                 # (H, W) uint16, 0 = invalid
    confidence: np.ndarray | None        # (H, W) uint8 or None if it did not arrive in time
    header: dict[str, Any]               # the depth sample's header
    received_ns: int                     # wall clock when the depth sample arrived
    error: np.ndarray | None = None      # (H, W) float32 P(wrong), NaN = no estimate; None if the
                                         # device publishes none or it did not arrive in time

    @property
    def latency_ms(self) -> float:
        """Arrival time minus the stack's timestamp, in ms."""
        return (self.received_ns - int(self.header["timestamp_ns"])) / 1e6


@dataclass
class PointsSample:
    points: np.ndarray                   # (N, 3) float32 metres, optical frame
    header: dict[str, Any]               # the sample's header (see decode_points)


def _reply_payload(replies: Iterable[Any], what: str) -> bytes:
    for reply in replies:
        if reply.ok is not None:
            return reply.ok.payload.to_bytes()
        raise ConfigRejected(reply.err.payload.to_bytes().decode(errors="replace"))
    raise ConfigRejected(f"no reply from {what} (is the service running and reachable?)")


def get_config(session: zenoh.Session, device: str, *, prefix: str = "sl", timeout: float = 2.0) -> dict[str, Any]:
    """The active profile of ``device`` as a dict (ConfigRejected if there is no answer)."""
    key = f"{prefix}/{device}/config"
    return json.loads(_reply_payload(session.get(key, timeout=timeout), key))


def update_config(session: zenoh.Session, device: str, update: Mapping[str, Any] | bytes, *,
                  prefix: str = "sl", timeout: float = 2.0) -> dict[str, Any]:
    """Send a partial profile update; returns the new profile, or raises ConfigRejected(reason)."""
    key = f"{prefix}/{device}/config"
    payload = update if isinstance(update, bytes) else json.dumps(dict(update)).encode()
    return json.loads(_reply_payload(session.get(key, payload=payload, timeout=timeout), key))


def is_alive(session: zenoh.Session, device: str, *, prefix: str = "sl", timeout: float = 2.0) -> bool:
    """True if ``<prefix>/<device>/alive`` has a liveliness token."""
    key = f"{prefix}/{device}/alive"
    return any(r.ok is not None for r in session.liveliness().get(key, timeout=timeout))


class DepthSubscriber:
    """Client side: receive decoded depth (+ confidence) and status of one device.

    ``DepthSubscriber("sim-dlp", connect=["tcp/127.0.0.1:7451"])`` opens a peer session with
    multicast scouting off (or uses ``session``). `receive` returns `DepthSample` objects in
    arrival order; at most ``max_queue`` are buffered (older ones are dropped and counted in
    ``dropped``). ``status`` holds the latest status dict; with ``points=True`` ``points`` holds
    the latest `PointsSample` of ``sl/<device>/points``.
    """

    def __init__(self, device: str, *, connect: Iterable[str] = ("tcp/127.0.0.1:7451",), prefix: str = "sl",
                 session: zenoh.Session | None = None, max_queue: int = 8, points: bool = False):
        self.device, self.prefix = device, prefix
        self._own_session = session is None
        self.session = session if session is not None else zenoh.open(make_config(connect=connect))
        self._samples: queue.Queue[tuple[np.ndarray, dict[str, Any], int]] = queue.Queue(maxsize=max_queue)
        self._confidence: dict[int, np.ndarray] = {}
        self._error: dict[int, np.ndarray] = {}
        self._cond = threading.Condition()
        self.dropped = 0
        self.errors: list[str] = []
        self.status: dict[str, Any] | None = None
        self.points: PointsSample | None = None  # the latest point cloud (with points=True)
        self._closed = False
        base = f"{prefix}/{device}"
        self._subs = [
            self.session.declare_subscriber(f"{base}/depth", self._on_depth),
            self.session.declare_subscriber(f"{base}/confidence", self._on_confidence),
            self.session.declare_subscriber(f"{base}/error", self._on_error),
            self.session.declare_subscriber(f"{base}/status", self._on_status),
        ]
        if points:
            self._subs.append(self.session.declare_subscriber(f"{base}/points", self._on_points))

    def _on_depth(self, sample: zenoh.Sample) -> None:
        received = time.time_ns()
        try:
            header = decode_header(sample.attachment.to_bytes() if sample.attachment is not None else None)
            depth = decode_image(sample.payload.to_bytes(), header)
        except ValueError as exc:
            self.errors.append(f"depth: {exc}")
            return
        while True:
            try:
                self._samples.put_nowait((depth, header, received))
                return
            except queue.Full:
                try:
                    self._samples.get_nowait()
                    self.dropped += 1
                except queue.Empty:
                    pass

    def _on_confidence(self, sample: zenoh.Sample) -> None:
        try:
            header = decode_header(sample.attachment.to_bytes() if sample.attachment is not None else None)
            image = decode_image(sample.payload.to_bytes(), header)
        except ValueError as exc:
            self.errors.append(f"confidence: {exc}")
            return
        with self._cond:
            self._confidence[int(header["sequence"])] = image
            while len(self._confidence) > 32:
                self._confidence.pop(next(iter(self._confidence)))
            self._cond.notify_all()

    def _on_error(self, sample: zenoh.Sample) -> None:
        try:
            header = decode_header(sample.attachment.to_bytes() if sample.attachment is not None else None)
            image = decode_image(sample.payload.to_bytes(), header)
        except ValueError as exc:
            self.errors.append(f"error: {exc}")
            return
        with self._cond:
            self._error[int(header["sequence"])] = image
            while len(self._error) > 32:
                self._error.pop(next(iter(self._error)))
            self._cond.notify_all()

    def _on_points(self, sample: zenoh.Sample) -> None:
        try:
            xyz, header = decode_points(sample.payload.to_bytes(),
                                        sample.attachment.to_bytes() if sample.attachment is not None else None)
        except ValueError as exc:
            self.errors.append(f"points: {exc}")
            return
        self.points = PointsSample(xyz, header)

    def _on_status(self, sample: zenoh.Sample) -> None:
        try:
            self.status = json.loads(sample.payload.to_bytes())
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            self.errors.append(f"status: {exc}")

    def receive(self, timeout: float = 1.0, *, confidence_wait: float = 0.2) -> DepthSample | None:
        """The next depth sample (None after ``timeout`` s); waits up to ``confidence_wait`` s for
        the confidence map with the same sequence, and for its error image when the depth header
        says one was published (``"error": true``)."""
        try:
            depth, header, received = self._samples.get(timeout=timeout)
        except queue.Empty:
            return None
        seq = int(header["sequence"])
        with self._cond:
            want_error = bool(header.get("error"))
            self._cond.wait_for(lambda: seq in self._confidence and (not want_error or seq in self._error),
                                timeout=confidence_wait)
            conf = self._confidence.pop(seq, None)
            error = self._error.pop(seq, None)
            for old in [s for s in self._error if s < seq]:
                del self._error[old]
        return DepthSample(depth, conf, header, received, error)

    def get_config(self, timeout: float = 2.0) -> dict[str, Any]:
        return get_config(self.session, self.device, prefix=self.prefix, timeout=timeout)

    def update_config(self, update: Mapping[str, Any] | bytes, timeout: float = 2.0) -> dict[str, Any]:
        return update_config(self.session, self.device, update, prefix=self.prefix, timeout=timeout)

    def is_alive(self, timeout: float = 2.0) -> bool:
        return is_alive(self.session, self.device, prefix=self.prefix, timeout=timeout)

    def close(self) -> None:
        """Undeclare the subscribers, then close the session (if owned)."""
        if self._closed:
            return
        self._closed = True
        for sub in self._subs:
            try:
                sub.undeclare()
            except Exception:
                pass
        if self._own_session:
            self.session.close()

    def __enter__(self) -> "DepthSubscriber":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

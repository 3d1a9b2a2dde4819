"""ROS 2 over rmw_zenoh without a bridge: message types, REP 2016 type hashes, CDR, key expressions.

Everything here follows rmw_zenoh's design document (docs/design.md of ros2/rmw_zenoh) and is pure
(no zenoh session): `edge.io.ros_sink.RosSink` does the publishing.

* **Topic key expression** ``<domain_id>/<fully qualified topic without leading '/'>/<dds type
  name>/<type hash>``, e.g. ``0/sim_dlp/depth/image_rect_raw/sensor_msgs::msg::dds_::Image_/RIHS01_d31d...``.
* **Payload**: the message in CDR as on DDS: the 4-byte encapsulation header ``00 01 00 00``
  (CDR, little endian) and the plain-CDR body, primitives aligned to their size from the byte after
  the header, strings as uint32 length (with the terminating NUL) + bytes + NUL, sequences as
  uint32 count + elements (`serialize_cdr`).
* **Attachment** of every put: int64 sequence number (LE), int64 source timestamp (ns since the
  UNIX epoch, LE), one byte GID length (16), the 16-byte publisher GID (`attachment`).
* **Liveliness tokens** (`node_token`, `publisher_token`):
  ``@ros2_lv/<domain>/<session zid>/<node id>/<node id>/NN/<enclave>/<namespace>/<node>`` and
  ``@ros2_lv/<domain>/<zid>/<node id>/<entity id>/MP/<enclave>/<namespace>/<node>/<topic>/<type>/<hash>/<qos>``
  where ``/`` inside a field is written ``%`` (the default enclave and namespace ``/`` become
  ``%``) and ``<qos>`` is rmw_zenoh's compact ``qos_to_keyexpr`` string (`qos_keyexpr`).
* **GID** of an entity: XXH3-128 of its liveliness key expression, low 64 bits then high 64 bits,
  little endian (as rmw_zenoh's liveliness_utils does) (`entity_gid`).
* **Type hashes** (`type_hash`): REP 2016 ``RIHS01_`` + sha256 of the JSON type description
  (``type_description`` + ``referenced_type_descriptions`` sorted by name, field types as
  type_description_interfaces/FieldType ids, no default values), computed from `MESSAGES`; the
  test suite checks them against an independent implementation (rosbags) and the published hash of
  sensor_msgs/msg/Image.

ROS names allow ``[A-Za-z0-9_/]`` only: `ros_name` maps a device name (``sim-dlp`` -> ``sim_dlp``).
Frame ids follow REP 103 / 105: ``<name>_optical_frame`` (x right, y down, z forward) for the camera.
"""

from __future__ import annotations

import hashlib
import json
import re
import struct
from typing import Any, Iterable, Mapping

import numpy as np

from edge.device import frame_ids, ros_name  # noqa: F401  (device naming; re-exported)

__all__ = [
    "MESSAGES",
    "ADMIN_SPACE",
    "DEFAULT_QOS",
    "ros_name",
    "dds_type_name",
    "type_description",
    "type_hash",
    "topic_keyexpr",
    "node_token",
    "publisher_token",
    "qos_keyexpr",
    "entity_gid",
    "attachment",
    "parse_attachment",
    "serialize_cdr",
    "image_message",
    "camera_info_message",
    "point_cloud2_message",
    "tf_message",
    "domain_id_from_env",
    "frame_ids",
    "OPTICAL_ROTATION",
]

#: Fields of every message edge publishes and of the types they reference, in declaration order
#: (the .msg files of sensor_msgs, std_msgs and builtin_interfaces; constants are not part of the
#: wire format or the hash).  Types: primitives, ``T[]`` (sequence), ``T[N]`` (array), nested names.
MESSAGES: dict[str, list[tuple[str, str]]] = {
    "builtin_interfaces/msg/Time": [("sec", "int32"), ("nanosec", "uint32")],
    "std_msgs/msg/Header": [("stamp", "builtin_interfaces/msg/Time"), ("frame_id", "string")],
    "sensor_msgs/msg/Image": [
        ("header", "std_msgs/msg/Header"), ("height", "uint32"), ("width", "uint32"),
        ("encoding", "string"), ("is_bigendian", "uint8"), ("step", "uint32"), ("data", "uint8[]")],
    "sensor_msgs/msg/RegionOfInterest": [
        ("x_offset", "uint32"), ("y_offset", "uint32"), ("height", "uint32"), ("width", "uint32"),
        ("do_rectify", "bool")],
    "sensor_msgs/msg/CameraInfo": [
        ("header", "std_msgs/msg/Header"), ("height", "uint32"), ("width", "uint32"),
        ("distortion_model", "string"), ("d", "float64[]"), ("k", "float64[9]"), ("r", "float64[9]"),
        ("p", "float64[12]"), ("binning_x", "uint32"), ("binning_y", "uint32"),
        ("roi", "sensor_msgs/msg/RegionOfInterest")],
    "sensor_msgs/msg/PointField": [
        ("name", "string"), ("offset", "uint32"), ("datatype", "uint8"), ("count", "uint32")],
    "geometry_msgs/msg/Vector3": [("x", "float64"), ("y", "float64"), ("z", "float64")],
    "geometry_msgs/msg/Quaternion": [("x", "float64"), ("y", "float64"), ("z", "float64"), ("w", "float64")],
    "geometry_msgs/msg/Transform": [("translation", "geometry_msgs/msg/Vector3"),
                                    ("rotation", "geometry_msgs/msg/Quaternion")],
    "geometry_msgs/msg/TransformStamped": [("header", "std_msgs/msg/Header"), ("child_frame_id", "string"),
                                           ("transform", "geometry_msgs/msg/Transform")],
    "tf2_msgs/msg/TFMessage": [("transforms", "geometry_msgs/msg/TransformStamped[]")],
    "sensor_msgs/msg/PointCloud2": [
        ("header", "std_msgs/msg/Header"), ("height", "uint32"), ("width", "uint32"),
        ("fields", "sensor_msgs/msg/PointField[]"), ("is_bigendian", "bool"), ("point_step", "uint32"),
        ("row_step", "uint32"), ("data", "uint8[]"), ("is_dense", "bool")],
}

ADMIN_SPACE = "@ros2_lv"
#: rmw_zenoh's default QoS (qos.cpp): RELIABLE, VOLATILE, KEEP_LAST 42, infinite deadline /
#: lifespan / lease, AUTOMATIC liveliness.  Values are the rmw enum numbers.
_RMW_DEFAULT_QOS = {"reliability": 1, "durability": 2, "history": 1, "depth": 42}
#: what edge's publishers declare: reliable, volatile, keep last 10 (rclcpp's default depth)
DEFAULT_QOS = {"reliability": 1, "durability": 2, "history": 1, "depth": 10}

# type_description_interfaces/msg/FieldType ids
_FIELD_TYPE_IDS = {"int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7,
                   "int64": 8, "uint64": 9, "float32": 10, "float64": 11, "char": 13, "bool": 15,
                   "byte": 16, "string": 17}
_NESTED, _ARRAY, _SEQUENCE = 1, 48, 144
_PRIMITIVE_FORMAT = {"int8": "b", "uint8": "B", "int16": "h", "uint16": "H", "int32": "i", "uint32": "I",
                     "int64": "q", "uint64": "Q", "float32": "f", "float64": "d", "char": "B",
                     "bool": "?", "byte": "B"}
_NUMPY = {"int8": "i1", "uint8": "u1", "int16": "<i2", "uint16": "<u2", "int32": "<i4", "uint32": "<u4",
          "int64": "<i8", "uint64": "<u8", "float32": "<f4", "float64": "<f8", "byte": "u1", "char": "u1",
          "bool": "?"}
_TYPE = re.compile(r"^(?P<base>[A-Za-z0-9_/]+?)(?:\[(?P<size>\d*)\])?$")


def _parse(t: str) -> tuple[str, int | None]:
    """'float64[9]' -> ('float64', 9); 'uint8[]' -> ('uint8', -1); 'uint32' -> ('uint32', None)."""
    m = _TYPE.match(t)
    if m is None:
        raise ValueError(f"expected a ROS field type like uint8, float64[9] or pkg/msg/Type[], got {t!r}")
    size = m.group("size")
    return m.group("base"), (None if size is None else (-1 if size == "" else int(size)))


#: Rotation (x, y, z, w) of a REP 103 optical frame (x right, y down, z forward) in its body frame
#: (x forward, y left, z up).
OPTICAL_ROTATION = (-0.5, 0.5, -0.5, 0.5)


def dds_type_name(ros_type: str) -> str:
    """``sensor_msgs/msg/Image`` -> ``sensor_msgs::msg::dds_::Image_`` (the CDR / DDS type name)."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def domain_id_from_env(environ: Mapping[str, str]) -> int:
    """The ROS domain id from ``ROS_DOMAIN_ID`` (default 0); ValueError naming a bad value."""
    raw = environ.get("ROS_DOMAIN_ID", "").strip()
    if not raw:
        return 0
    if not raw.isdigit() or not 0 <= int(raw) <= 232:
        raise ValueError(f"ROS_DOMAIN_ID: expected an integer 0..232, got {raw!r}")
    return int(raw)


# -- REP 2016 type hashes ------------------------------------------------------------------------


def _field_type(t: str) -> dict[str, Any]:
    base, size = _parse(t)
    nested = base not in _FIELD_TYPE_IDS
    tid = _NESTED if nested else _FIELD_TYPE_IDS[base]
    capacity = 0
    if size == -1:
        tid += _SEQUENCE
    elif size is not None:
        tid += _ARRAY
        capacity = size
    return {"type_id": tid, "capacity": capacity, "string_capacity": 0,
            "nested_type_name": base if nested else ""}


def _referenced(ros_type: str, seen: set[str]) -> None:
    for _, t in MESSAGES[ros_type]:
        base, _ = _parse(t)
        if base not in _FIELD_TYPE_IDS and base not in seen:
            if base not in MESSAGES:
                raise ValueError(f"type {base!r} referenced by {ros_type} is not in edge.io.ros.MESSAGES")
            seen.add(base)
            _referenced(base, seen)


def type_description(ros_type: str) -> dict[str, Any]:
    """The REP 2016 hashable type description of ``ros_type`` (no default values)."""
    if ros_type not in MESSAGES:
        raise ValueError(f"expected one of {sorted(MESSAGES)}, got {ros_type!r}")

    def one(name: str) -> dict[str, Any]:
        return {"type_name": name,
                "fields": [{"name": f, "type": _field_type(t)} for f, t in MESSAGES[name]]}

    refs: set[str] = set()
    _referenced(ros_type, refs)
    return {"type_description": one(ros_type),
            "referenced_type_descriptions": [one(r) for r in sorted(refs)]}


def type_hash(ros_type: str) -> str:
    """``RIHS01_<sha256 hex>`` of the type description, serialised as rosidl does (json.dumps with
    ``separators=(", ", ": ")``, keys in declaration order, ASCII)."""
    text = json.dumps(type_description(ros_type), ensure_ascii=True, separators=(", ", ": "), sort_keys=False)
    return "RIHS01_" + hashlib.sha256(text.encode("utf-8")).hexdigest()


# -- key expressions and liveliness --------------------------------------------------------------


def _mangle(name: str) -> str:
    return name.replace("/", "%")


def topic_keyexpr(domain_id: int, topic: str, ros_type: str) -> str:
    """``<domain>/<topic without leading/trailing '/'>/<dds type>/<RIHS01 hash>``."""
    return f"{int(domain_id)}/{topic.strip('/')}/{dds_type_name(ros_type)}/{type_hash(ros_type)}"


def qos_keyexpr(qos: Mapping[str, int] = DEFAULT_QOS) -> str:
    """rmw_zenoh's compact QoS string: ``<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:
    <lifespan s>,<ns>:<liveliness>,<lease s>,<ns>`` where a value equal to rmw_zenoh's default is
    left empty (edge leaves deadline, lifespan and liveliness at their defaults): reliable /
    volatile / keep-last 10 -> ``::,10:,:,:,,``."""
    def part(key: str) -> str:
        return "" if int(qos[key]) == _RMW_DEFAULT_QOS[key] else str(int(qos[key]))

    return f"{part('reliability')}:{part('durability')}:{part('history')},{part('depth')}:,:,:,,"


def node_token(domain_id: int, zid: str, node_id: int, node: str, namespace: str = "/",
               enclave: str = "/") -> str:
    """Liveliness key of a node (entity kind ``NN``)."""
    return (f"{ADMIN_SPACE}/{int(domain_id)}/{zid}/{int(node_id)}/{int(node_id)}/NN/{_mangle(enclave)}/"
            f"{_mangle(namespace)}/{_mangle(node)}")


def publisher_token(domain_id: int, zid: str, node_id: int, entity_id: int, node: str, topic: str,
                    ros_type: str, *, namespace: str = "/", enclave: str = "/",
                    qos: Mapping[str, int] = DEFAULT_QOS) -> str:
    """Liveliness key of a publisher (entity kind ``MP``) on the fully qualified ``topic``."""
    return (f"{ADMIN_SPACE}/{int(domain_id)}/{zid}/{int(node_id)}/{int(entity_id)}/MP/{_mangle(enclave)}/"
            f"{_mangle(namespace)}/{_mangle(node)}/{_mangle(topic)}/{dds_type_name(ros_type)}/"
            f"{type_hash(ros_type)}/{qos_keyexpr(qos)}")


def entity_gid(token: str) -> bytes:
    """16-byte GID of the entity with liveliness key ``token``: XXH3-128, low then high 64 bits, LE."""
    import xxhash

    value = xxhash.xxh3_128_intdigest(token.encode())
    return (value & ((1 << 64) - 1)).to_bytes(8, "little") + (value >> 64).to_bytes(8, "little")


def attachment(sequence: int, timestamp_ns: int, gid: bytes) -> bytes:
    """The per-sample attachment: int64 sequence, int64 source timestamp (ns), uint8 16, GID (33 bytes)."""
    if len(gid) != 16:
        raise ValueError(f"expected a 16-byte GID, got {len(gid)} bytes")
    return struct.pack("<qqB", int(sequence), int(timestamp_ns), 16) + bytes(gid)


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence, source timestamp ns, gid) of an rmw_zenoh attachment."""
    if len(data) < 17 or data[16] != 16 or len(data) != 33:
        raise ValueError(f"expected a 33-byte rmw_zenoh attachment (seq, timestamp, 16, gid), got {len(data)} bytes")
    seq, ts = struct.unpack_from("<qq", data)
    return seq, ts, bytes(data[17:33])


# -- CDR -----------------------------------------------------------------------------------------


class _CdrWriter:
    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.pos = 0  # offset from the end of the encapsulation header

    def _put(self, b: Any) -> None:
        self.parts.append(b)
        self.pos += len(b)

    def align(self, n: int) -> None:
        pad = (-self.pos) % n
        if pad:
            self._put(b"\0" * pad)

    def primitive(self, base: str, value: Any) -> None:
        fmt = _PRIMITIVE_FORMAT[base]
        size = struct.calcsize(fmt)
        self.align(size)
        self._put(struct.pack("<" + fmt, value))

    def string(self, value: str) -> None:
        data = str(value).encode("utf-8") + b"\0"
        self.primitive("uint32", len(data))
        self._put(data)

    def array(self, base: str, values: Any, count: int | None) -> None:
        """Primitive array (count = N) or sequence (count None: uint32 length first)."""
        if isinstance(values, (bytes, bytearray, memoryview)) and base in ("uint8", "byte", "char"):
            data = values
            n = len(data)
        else:  # no copy for a contiguous array of the right dtype: b"".join reads its buffer
            arr = np.ascontiguousarray(np.asarray(values), dtype=_NUMPY[base]).reshape(-1)
            n = arr.size
            data = memoryview(arr).cast("B") if n else b""
        if count is None:
            self.primitive("uint32", n)
        elif n != count:
            raise ValueError(f"expected {count} values for a {base}[{count}] array, got {n}")
        if n:
            self.align(np.dtype(_NUMPY[base]).itemsize)
            self._put(data)


def _write(w: _CdrWriter, ros_type: str, msg: Mapping[str, Any]) -> None:
    for name, t in MESSAGES[ros_type]:
        if name not in msg:
            raise ValueError(f"{ros_type}: missing field {name!r}")
        value = msg[name]
        base, size = _parse(t)
        if base in MESSAGES:
            if size is None:
                _write(w, base, value)
            else:
                items = list(value)
                if size == -1:
                    w.primitive("uint32", len(items))
                elif len(items) != size:
                    raise ValueError(f"{ros_type}.{name}: expected {size} items, got {len(items)}")
                for item in items:
                    _write(w, base, item)
        elif base == "string":
            if size is not None:
                items = list(value)
                if size == -1:
                    w.primitive("uint32", len(items))
                for item in items:
                    w.string(item)
            else:
                w.string(value)
        elif size is None:
            w.primitive(base, value)
        else:
            w.array(base, value, None if size == -1 else size)


def serialize_cdr(ros_type: str, msg: Mapping[str, Any]) -> bytes:
    """CDR (little endian, with the 4-byte encapsulation header) of ``msg``, a nested dict of the
    fields in `MESSAGES` (arrays as sequences, numpy arrays or bytes)."""
    if ros_type not in MESSAGES:
        raise ValueError(f"expected one of {sorted(MESSAGES)}, got {ros_type!r}")
    w = _CdrWriter()
    _write(w, ros_type, msg)
    return b"".join([b"\x00\x01\x00\x00", *w.parts])


# -- messages edge publishes ---------------------------------------------------------------------


def _header(timestamp_ns: int, frame_id: str) -> dict[str, Any]:
    return {"stamp": {"sec": int(timestamp_ns) // 1_000_000_000, "nanosec": int(timestamp_ns) % 1_000_000_000},
            "frame_id": frame_id}


_IMAGE_ENCODINGS = {np.dtype(np.uint16): "16UC1", np.dtype(np.uint8): "mono8", np.dtype(np.float32): "32FC1"}


def image_message(image: np.ndarray, *, timestamp_ns: int, frame_id: str) -> dict[str, Any]:
    """sensor_msgs/msg/Image of an (H, W) uint16 (``16UC1``, mm, REP 118), uint8 (``mono8``) or
    float32 (``32FC1``, NaN = no value as in REP 118; little endian, step 4 W) array."""
    image = np.asarray(image)
    if image.ndim != 2 or image.dtype not in _IMAGE_ENCODINGS:
        raise ValueError(f"expected an (H, W) uint16, uint8 or float32 image, got {image.dtype} {image.shape}")
    h, w = image.shape
    return {"header": _header(timestamp_ns, frame_id), "height": h, "width": w,
            "encoding": _IMAGE_ENCODINGS[image.dtype], "is_bigendian": 0, "step": w * image.dtype.itemsize,
            "data": np.ascontiguousarray(image, dtype=image.dtype.newbyteorder("<")).view(np.uint8).reshape(-1)}


def camera_info_message(k: Iterable[float], width: int, height: int, *, timestamp_ns: int,
                        frame_id: str) -> dict[str, Any]:
    """sensor_msgs/msg/CameraInfo of a rectified pinhole camera with 3x3 intrinsics ``k`` (row-major,
    pixels): plumb_bob with zero distortion, R = identity, P = [K | 0]."""
    kk = [float(v) for v in np.asarray(k, dtype=np.float64).reshape(9)]
    p = [kk[0], kk[1], kk[2], 0.0, kk[3], kk[4], kk[5], 0.0, 0.0, 0.0, 1.0, 0.0]
    return {"header": _header(timestamp_ns, frame_id), "height": int(height), "width": int(width),
            "distortion_model": "plumb_bob", "d": [0.0] * 5, "k": kk,
            "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], "p": p, "binning_x": 0, "binning_y": 0,
            "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}


_FLOAT32 = 7  # sensor_msgs/PointField FLOAT32


def point_cloud2_message(xyz: np.ndarray, *, timestamp_ns: int, frame_id: str) -> dict[str, Any]:
    """sensor_msgs/msg/PointCloud2 of (N, 3) points (metres): unorganised (height 1), fields x y z
    FLOAT32 at offsets 0, 4, 8, point_step 12, little endian, dense (no NaN)."""
    xyz = np.ascontiguousarray(np.asarray(xyz), dtype="<f4")
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise ValueError(f"expected (N, 3) points, got {xyz.shape}")
    n = xyz.shape[0]
    fields = [{"name": c, "offset": 4 * i, "datatype": _FLOAT32, "count": 1} for i, c in enumerate("xyz")]
    return {"header": _header(timestamp_ns, frame_id), "height": 1, "width": n, "fields": fields,
            "is_bigendian": False, "point_step": 12, "row_step": 12 * n, "data": xyz.view(np.uint8).reshape(-1),
            "is_dense": True}


def tf_message(device: str, baseline_m: float, *, timestamp_ns: int) -> dict[str, Any]:
    """tf2_msgs/msg/TFMessage of a device's frame tree (`frame_ids`): ``<name>_link`` ->
    ``<name>_optical_frame`` (REP 103 rotation), optical -> ``<name>_projector_optical_frame``
    (+``baseline_m`` along x)."""
    ids = frame_ids(device)
    x, y, z, w = OPTICAL_ROTATION

    def tf(parent: str, child: str, t: tuple[float, float, float], q: tuple[float, float, float, float]):
        return {"header": _header(timestamp_ns, parent), "child_frame_id": child,
                "transform": {"translation": dict(zip("xyz", map(float, t))),
                              "rotation": dict(zip("xyzw", map(float, q)))}}

    return {"transforms": [tf(ids["base"], ids["optical"], (0.0, 0.0, 0.0), (x, y, z, w)),
                           tf(ids["optical"], ids["projector"], (float(baseline_m), 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))]}

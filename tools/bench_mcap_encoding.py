"""Benchmark: foxglove.RawImage in MCAP with protobuf vs JSON-schema encoding.

Writes ``--frames`` 640x480 camera frames (simulated SL stripes + shot-like noise, mono8 and
mono16) per run, ``--repeats`` runs per variant, all in this process, and prints the median write
throughput (MB of pixels per second), the file size, and the protobuf / JSON ratios.

    python tools/bench_mcap_encoding.py [--frames 120] [--repeats 5] [--compression zstd]
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import statistics
import tempfile
import time

import numpy as np
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

RAW_IMAGE_JSON_SCHEMA = {
    "title": "foxglove.RawImage",
    "type": "object",
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
        "frame_id": {"type": "string"},
        "width": {"type": "integer"},
        "height": {"type": "integer"},
        "encoding": {"type": "string"},
        "step": {"type": "integer"},
        "data": {"type": "string", "contentEncoding": "base64"},
    },
}


def make_frames(n: int, bits: int, seed: int = 0) -> list[np.ndarray]:
    """n (480, 640) frames: vertical binary stripes of varying period, albedo ramp, Gaussian noise."""
    rng = np.random.default_rng(seed)
    x = np.arange(640)
    albedo = np.linspace(0.3, 1.0, 480)[:, None]
    top = (1 << bits) - 1
    dtype = np.uint8 if bits == 8 else np.uint16
    frames = []
    for i in range(n):
        stripes = ((x >> (i % 10)) & 1).astype(np.float32)[None, :]
        img = 0.15 + 0.7 * albedo * stripes + rng.normal(0, 0.02, (480, 640))
        frames.append(np.clip(img * top, 0, top).astype(dtype))
    return frames


def write(path: str, frames: list[np.ndarray], encoding: str, compression: CompressionType) -> float:
    """Write the frames; return seconds taken (encode + write + finish)."""
    start = time.perf_counter()
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=4 * 1024 * 1024, compression=compression, enable_crcs=True)
        w.start(profile="edge", library="bench")
        if encoding == "protobuf":
            sid = w.register_schema("foxglove.RawImage", "protobuf",
                                    build_file_descriptor_set(RawImage).SerializeToString())
        else:
            sid = w.register_schema("foxglove.RawImage", "jsonschema", json.dumps(RAW_IMAGE_JSON_SCHEMA).encode())
        cid = w.register_channel("/cam/raw", encoding if encoding == "protobuf" else "json", sid)
        enc = "mono8" if frames[0].dtype == np.uint8 else "mono16"
        for i, img in enumerate(frames):
            t = 1_700_000_000_000_000_000 + i * 8_333_333
            data = img.astype(img.dtype.newbyteorder("<"), copy=False).tobytes()
            if encoding == "protobuf":
                msg = RawImage(frame_id="camera", width=640, height=480, encoding=enc,
                               step=640 * img.itemsize, data=data)
                msg.timestamp.seconds, msg.timestamp.nanos = divmod(t, 1_000_000_000)
                payload = msg.SerializeToString()
            else:
                payload = json.dumps({
                    "timestamp": {"sec": t // 1_000_000_000, "nsec": t % 1_000_000_000},
                    "frame_id": "camera", "width": 640, "height": 480, "encoding": enc,
                    "step": 640 * img.itemsize, "data": base64.b64encode(data).decode("ascii"),
                }).encode()
            w.add_message(cid, t, payload, t, i)
        w.finish()
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=120, help="640x480 frames written per run (default 120)")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs; medians are reported (default 5)")
    ap.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd",
                    help="MCAP chunk compression (default zstd)")
    args = ap.parse_args()
    if args.frames < 1 or args.repeats < 1:  # --frames 0 failed with an IndexError
        raise ValueError(f"--frames and --repeats must be >= 1, got {args.frames} and {args.repeats}")
    compression = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[args.compression]
    print(f"{args.frames} frames of 640x480 per run, {args.repeats} runs, compression {args.compression}, "
          f"CRCs on; medians (timing noise: shared machine)")
    print(f"{'bits':>4} {'encoding':>9} {'MB/s':>8} {'file MB':>8} {'bytes/px':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for bits in (8, 12):
            frames = make_frames(args.frames, bits)
            pixel_mb = sum(f.nbytes for f in frames) / 1e6
            results = {}
            for encoding in ("protobuf", "json"):
                path = os.path.join(tmp, f"{encoding}.mcap")
                times = [write(path, frames, encoding, compression) for _ in range(args.repeats)]
                size = os.path.getsize(path)
                results[encoding] = (pixel_mb / statistics.median(times), size / 1e6)
                print(f"{bits:>4} {encoding:>9} {results[encoding][0]:8.1f} {size / 1e6:8.2f} "
                      f"{size / (args.frames * 640 * 480):8.3f}")
            (pm, ps), (jm, js) = results["protobuf"], results["json"]
            print(f"{bits:>4} protobuf/json: throughput x{pm / jm:.2f}, file size x{ps / js:.2f}")


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))

"""Cost per depth map of the output sinks on the decode thread: zenoh depth only (baseline), + the
point cloud key, + ROS 2 (Image, CameraInfo, PointCloud2 over rmw_zenoh), + Foxglove live.

    python tools/bench_outputs.py [--profile sim-dlp] [--repeats 50]

Every sink publishes on a real zenoh session on loopback (no subscriber; a Foxglove server with no
client), with a depth map of the profile's size (a smooth surface, 97 % valid) and a new
`DepthResult` each call, so the point cloud is computed every time.  Prints the median ms per
depth map and the ratio to the baseline (medians of ``--repeats`` calls, same process).
"""

from __future__ import annotations

import argparse
import dataclasses
import socket
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--profile", default="sim-dlp", help="profile name or TOML (default sim-dlp)")
    ap.add_argument("--repeats", type=int, default=50, help="calls per configuration (default 50)")
    args = ap.parse_args(argv)
    if args.repeats < 3:
        raise ValueError(f"expected --repeats >= 3, got {args.repeats}")

    from edge.profiles import apply_update, load_profile
    from edge.runtime.pipeline import DepthResult
    from edge.io.publish import ZenohSink
    from edge.io.ros_sink import RosSink

    base = apply_update(load_profile(args.profile),
                        {"zenoh": {"listen": [f"tcp/127.0.0.1:{_free_port()}"], "connect": []}})
    h, w = base.camera.height, base.camera.width
    yy, xx = np.mgrid[0:h, 0:w]
    depth = (900 + 300 * np.sin(xx / 40.0) * np.cos(yy / 50.0)).astype(np.uint16)
    depth[np.random.default_rng(0).random((h, w)) < 0.03] = 0
    conf = np.full((h, w), 200, np.uint8)
    template = DepthResult(stack=0, sequence=0, timestamp_ns=time.time_ns(), received_ns=time.time_ns(),
                           depth_mm=depth, confidence=conf, column=np.zeros((h, w), np.int32))

    def timed(sinks) -> float:
        out = []
        for i in range(args.repeats + 3):
            r = dataclasses.replace(template, stack=i)
            t0 = time.perf_counter()
            for s in sinks:
                s.on_result(r)
            if i >= 3:
                out.append(time.perf_counter() - t0)
        return statistics.median(out) * 1e3

    rows = []
    no_points = apply_update(base, {"points": {"publish": False}})
    z0 = ZenohSink(no_points)
    try:
        rows.append(("zenoh depth + confidence (baseline)", timed([z0])))
    finally:
        z0.close()
    z = ZenohSink(base)
    ros = RosSink(base, session=z.publisher.session, environ={})
    try:
        rows.append((f"+ sl/<device>/points (stride {base.points.stride})", timed([z])))
        rows.append(("+ ROS 2: Image x2, CameraInfo x2, PointCloud2, TF", timed([z, ros])))
        try:
            from edge.io.foxglove_sink import FoxgloveSink

            fox = FoxgloveSink(base, port=0)
        except ValueError as exc:
            print(f"(Foxglove row skipped: {exc})")
        else:
            try:
                rows.append(("+ Foxglove live (no client)", timed([z, ros, fox])))
            finally:
                fox.close()
    finally:
        ros.close()
        z.close()
    ref = rows[0][1]
    print(f"{base.name}: {w}x{h} depth, {int(np.count_nonzero(depth))} valid pixels, median of {args.repeats}")
    print("| sinks per depth map | median ms | vs baseline |\n|---|---|---|")
    for name, ms in rows:
        print(f"| {name} | {ms:.2f} | {ms / ref:.1f}x |")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))

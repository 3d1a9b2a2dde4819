"""``edge subscribe``: receive depth from a running service, print rates and latency, save a PNG.

    edge subscribe [--device sim-dlp] [--connect tcp/127.0.0.1:7451] [--png depth.png]
                   [--ply cloud.ply] [--count N] [--seconds S]

Prints one line per second (depth maps/s, median and max latency in ms, dropped, last status
fps) and a summary; ``--png`` writes the last depth map colour-mapped (cv2.COLORMAP_TURBO, invalid
pixels black); ``--ply`` writes the last point cloud of ``sl/<device>/points`` (metres, camera
optical frame) with `edge.io.ply.write_ply`. Exit 1 if no depth map (or, with --ply, no cloud) arrived.

    edge subscribe --all [--prefix sl] [--connect ENDPOINT ...] [--seconds S] [--interval I]

lists every device under the prefix from this one subscriber (`edge.io.zenoh_monitor`): its
liveliness, depth maps/s and latency measured here (over the last 5 s), and its own status (fps,
latency, drops, router reconnects), as a table refreshed every ``--interval`` s. Exit 1 if no device was seen.
"""

from __future__ import annotations

import argparse
import statistics
import time

from edge.profiles import DEFAULT_PROFILE

from ._args import check_output_file
from ._pictures import colorize_depth


def _run(args: argparse.Namespace) -> int:
    from edge.io.zenoh import DepthSubscriber

    if args.count is not None and args.count < 1:
        raise ValueError(f"expected --count >= 1, got {args.count}")
    if args.seconds <= 0:
        raise ValueError(f"expected --seconds > 0, got {args.seconds}")
    # the outputs are written after the whole subscription: a path that cannot be written fails now
    if args.png:
        import cv2

        check_output_file(args.png, option="--png")
        if not cv2.haveImageWriter(args.png):
            raise ValueError(f"--png {args.png}: expected an image file name such as depth.png")
    if args.ply:
        check_output_file(args.ply, option="--ply")
    total, latencies, last = 0, [], None
    with DepthSubscriber(args.device, connect=args.connect, prefix=args.prefix, points=bool(args.ply)) as sub:
        start = time.monotonic()
        tick, window = start, []
        while time.monotonic() - start < args.seconds and (args.count is None or total < args.count):
            sample = sub.receive(timeout=0.2)
            if sample is not None:
                total += 1
                last = sample
                latencies.append(sample.latency_ms)
                window.append(sample.latency_ms)
            now = time.monotonic()
            if now - tick >= 1.0:
                fps = (sub.status or {}).get("fps", "-")
                lat = f"{statistics.median(window):.1f}/{max(window):.1f}" if window else "-/-"
                print(f"{len(window) / (now - tick):6.1f} depth/s  latency p50/max {lat} ms  "
                      f"dropped {sub.dropped}  service fps {fps}", flush=True)
                tick, window = now, []
        if args.ply and sub.points is None and last is not None:  # the cloud follows its depth map
            wait_until = time.monotonic() + 2.0
            while sub.points is None and time.monotonic() < wait_until:
                time.sleep(0.05)
        elapsed = time.monotonic() - start
        errors = list(sub.errors)
        cloud = sub.points
    if last is None:
        print(f"no depth from {args.prefix}/{args.device} in {elapsed:.1f} s (connect {', '.join(args.connect)})")
        return 1
    lat = sorted(latencies)
    p99 = lat[min(len(lat) - 1, int(round(0.99 * (len(lat) - 1))))]
    print(f"received {total} depth maps in {elapsed:.1f} s ({total / elapsed:.1f}/s); latency ms p50 "
          f"{statistics.median(lat):.1f} p99 {p99:.1f}; last {last.header['width']}x{last.header['height']} "
          f"seq {last.header['sequence']}, valid {(last.depth_mm > 0).mean():.1%}")
    for e in errors[:3]:
        print(f"bad sample: {e}")
    if args.png:
        import cv2

        if not cv2.imwrite(args.png, colorize_depth(last.depth_mm)):
            raise ValueError(f"could not write PNG to {args.png!r}")
        print(f"wrote {args.png}")
    if args.ply:
        from edge.io.ply import write_ply

        if cloud is None:
            print(f"no point cloud from {args.prefix}/{args.device}/points (is [points] publish off?)")
            return 1
        try:
            write_ply(args.ply, cloud.points)
        except OSError as exc:
            raise ValueError(f"could not write PLY to {args.ply!r}: {exc.strerror or exc}") from None
        print(f"wrote {args.ply} ({cloud.points.shape[0]} points, frame {cloud.header.get('frame_id', '')})")
    return 0


def _run_all(args: argparse.Namespace) -> int:
    import sys

    from edge.io.zenoh import make_config
    from edge.io.zenoh_monitor import DeviceMonitor, format_table

    if args.png or args.ply or args.count is not None:
        raise ValueError("--all lists every device; --png, --ply and --count apply to one --device")
    if args.seconds <= 0:
        raise ValueError(f"expected --seconds > 0, got {args.seconds}")
    if not args.interval > 0:
        raise ValueError(f"expected --interval > 0, got {args.interval}")
    import zenoh

    tty = sys.stdout.isatty()
    session = zenoh.open(make_config(connect=args.connect))
    try:
        with DeviceMonitor(session, args.prefix) as monitor:
            start = time.monotonic()
            rows = []
            while True:
                left = args.seconds - (time.monotonic() - start)
                time.sleep(max(0.0, min(args.interval, left)))
                rows = monitor.rows(window_s=max(args.interval, 5.0))
                elapsed = time.monotonic() - start
                lines = [f"{args.prefix}/* at {elapsed:.1f} s ({len(rows)} devices, {sum(r.alive for r in rows)} alive)"]
                lines += format_table(rows)
                print(("\x1b[H\x1b[J" if tty else "") + "\n".join(lines), flush=True)
                if elapsed >= args.seconds:
                    break
            errors = list(monitor.errors)
    finally:
        session.close()
    for e in errors[:3]:
        print(f"bad sample: {e}")
    if not rows:
        print(f"no device under {args.prefix}/ in {args.seconds:g} s (connect {', '.join(args.connect)})")
        return 1
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("subscribe", help="receive depth over zenoh; print rates, latency; save a PNG")
    parser.add_argument("--device", default=DEFAULT_PROFILE, help="device name in the key space (default %(default)s)")
    parser.add_argument("--prefix", default="sl", help="key prefix (default %(default)s)")
    parser.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                        help="zenoh endpoint to connect to (repeatable; default tcp/127.0.0.1:7451)")
    parser.add_argument("--png", default=None, help="write the last depth map colour-mapped to this PNG")
    parser.add_argument("--ply", default=None, metavar="FILE",
                        help="write the last point cloud (sl/<device>/points, metres, optical frame) to this PLY")
    parser.add_argument("--count", type=int, default=None, help="stop after N depth maps")
    parser.add_argument("--seconds", type=float, default=10.0, help="stop after S seconds (default %(default)s)")
    parser.add_argument("--all", action="store_true",
                        help="list every device under --prefix (liveliness, status, depth rate and latency "
                             "measured here over the last 5 s) as a table refreshed every --interval s")
    parser.add_argument("--interval", type=float, default=1.0,
                        help="--all: seconds between table refreshes (default %(default)s)")
    parser.set_defaults(func=lambda a: (_run_all if a.all else _run)(_defaults(a)))


def _defaults(args: argparse.Namespace) -> argparse.Namespace:
    from types import SimpleNamespace

    from edge.io.zenoh_check import check_endpoints

    if not args.connect:
        args.connect = ["tcp/127.0.0.1:7451"]
    check_endpoints(SimpleNamespace(listen=[], connect=args.connect, mode="peer"))  # zenoh's own text is JSON5
    return args

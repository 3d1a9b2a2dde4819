"""``edge run``: the depth service - sensor -> decode -> depth -> zenoh (+ MCAP recording)."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
from typing import Any, Iterator


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "run", help="run the depth service (default: simulated sensor, profile sim-dlp)",
        description="Run the depth service: capture stacks from the sensor, decode them in one thread, "
                    "publish depth/confidence/status over zenoh and optionally record MCAP. "
                    "SIGINT/SIGTERM stop it cleanly (the recording is finalised).")
    p.add_argument("--profile", default="sim-dlp", help="firmware profile name or TOML path (default: sim-dlp)")
    p.add_argument("--sensor", choices=("sim", "replay", "oak", "event"),
                   help="sensor backend (default: the profile's sensor.backend)")
    p.add_argument("--replay", metavar="FILE", help="recording for --sensor replay")
    p.add_argument("--record", metavar="OUT.mcap", help="record raw frames, depth and confidence to MCAP")
    stop = p.add_mutually_exclusive_group()
    stop.add_argument("--stacks", type=int, metavar="N", help="stop after N depth maps")
    stop.add_argument("--seconds", type=float, metavar="S", help="stop after S seconds")
    p.add_argument("--max-speed", action="store_true", help="simulated/replayed sensor runs as fast as possible")
    p.add_argument("--no-zenoh", action="store_true", help="do not open a zenoh session")
    p.add_argument("--listen", action="append", metavar="ENDPOINT",
                   help="zenoh listen endpoint(s), overriding the profile (e.g. tcp/127.0.0.1:7450)")
    p.add_argument("--connect", action="append", metavar="ENDPOINT", help="zenoh endpoint(s) to connect to")
    p.add_argument("--ros", action="store_true",
                   help="also publish ROS 2 topics over rmw_zenoh (Image, CameraInfo, PointCloud2): connects to "
                        "the rmw_zenohd router of the profile's [ros] table (default tcp/localhost:7447); "
                        "domain from ROS_DOMAIN_ID (default 0)")
    p.add_argument("--foxglove", nargs="?", type=int, const=8765, default=None, metavar="PORT",
                   help="serve depth, confidence, point cloud, calibration and frame tree to the Foxglove app "
                        "over its WebSocket protocol on 127.0.0.1:PORT (default 8765; needs edge[foxglove])")
    p.add_argument("--mode", choices=("peer", "client"),
                   help="zenoh mode, overriding the profile: 'client' talks only to the --connect routers "
                        "(and listens nowhere unless --listen is given), 'peer' also accepts direct connections")
    p.add_argument("--connect-timeout", type=float, metavar="S",
                   help="client mode: wait up to S s at start-up for a --connect router (default: the profile's "
                        "zenoh.connect_timeout_s, 0 = fail at once)")
    p.add_argument("--interference", action="store_true",
                   help="event / light-curtain simulators: add an unsynchronised second device nearby")
    p.add_argument("--poses", type=int, default=0, metavar="K",
                   help="sim: pre-render K poses of the motion and cycle them (0 = render live)")
    p.add_argument("--queue", type=int, default=1, metavar="N",
                   help="stacks waiting for the decoder before the oldest is dropped (default 1: freshest)")
    p.add_argument("--bar", action="store_true", help="tqdm progress bar instead of one line per depth map")
    p.add_argument("--quiet", action="store_true", help="only the final summary")
    p.set_defaults(func=run)


@contextlib.contextmanager
def stop_on_signals(stop: Any) -> Iterator[list[int]]:
    """Call ``stop()`` on SIGINT / SIGTERM while the block runs (main thread only); yields the
    list of signals received."""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def handler(signum: int, _frame: Any) -> None:
        received.append(signum)
        stop()

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield received
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def load_run_profile(args: argparse.Namespace):
    """The profile named by ``--profile`` with command-line zenoh overrides applied."""
    from edge.profiles import apply_update, load_profile

    profile = load_profile(args.profile)
    zenoh: dict[str, Any] = {}
    if getattr(args, "listen", None):
        zenoh["listen"] = list(args.listen)
    if getattr(args, "connect", None):
        zenoh["connect"] = list(args.connect)
    if getattr(args, "mode", None):
        zenoh["mode"] = args.mode
        if args.mode == "client" and not getattr(args, "listen", None):
            zenoh["listen"] = []  # a client reaches everyone through its routers: no port to clash
    if getattr(args, "connect_timeout", None) is not None:
        zenoh["connect_timeout_s"] = args.connect_timeout
    update: dict[str, Any] = {"zenoh": zenoh} if zenoh else {}
    if getattr(args, "ros", False):
        update["ros"] = {"enabled": True}
    if update:
        profile = apply_update(profile, update, source=f"{profile.source} + command line")
    if profile.ros.enabled and profile.ros.router not in profile.zenoh.connect:
        # ROS mode: connect to the rmw_zenohd router (do not listen on its port)
        profile = apply_update(profile, {"zenoh": {"connect": [*profile.zenoh.connect, profile.ros.router]}},
                               source=profile.source)
    return profile


def build_service(profile, args: argparse.Namespace, *, sinks: list[Any] | None = None):
    """Sensor, publisher, recorder and `Service` for ``edge run`` arguments (see `register`)."""
    from edge.runtime.service import Service
    from edge.sensors import open_sensor

    sensor = open_sensor(profile, args.sensor, replay_path=args.replay, max_speed=args.max_speed,
                         poses=args.poses, interference=getattr(args, "interference", False))
    if args.sensor == "replay" or (args.sensor is None and profile.sensor.backend == "replay"):
        profile = sensor.profile  # decode with the recorded profile
    sinks = list(sinks or [])
    recorder = None
    service = None
    try:
        if args.record:
            from edge.runtime.recording import RecordingThread

            recorder = RecordingThread(args.record, profile, sensor_metadata=sensor.info.metadata)
        service = Service(profile, sensor, sinks=sinks, recorder=recorder, queue_capacity=args.queue)
        zenoh_sink = None
        if not args.no_zenoh:
            from edge.runtime.publish import ZenohSink

            zenoh_sink = ZenohSink(profile, service)
            service.sinks.append(zenoh_sink)
        if profile.ros.enabled:
            from edge.runtime.ros_sink import RosSink

            ros_sink = RosSink(profile, session=zenoh_sink.publisher.session if zenoh_sink else None)
            # before the zenoh sink: it undeclares its entities before that sink closes the shared session
            service.sinks.insert(service.sinks.index(zenoh_sink) if zenoh_sink else len(service.sinks), ros_sink)
        if getattr(args, "foxglove", None) is not None:
            from edge.runtime.foxglove_sink import FoxgloveSink

            service.sinks.append(FoxgloveSink(profile, port=args.foxglove))
    except BaseException:
        for s in (service.sinks if service is not None else sinks):
            s.close()
        if recorder is not None:
            recorder.close()
        raise
    return service


def run(args: argparse.Namespace) -> int:
    from edge.runtime.console import ConsoleSink, summary_lines

    if args.stacks is not None and args.stacks < 1:
        raise ValueError(f"--stacks must be >= 1, got {args.stacks}")
    if args.seconds is not None and not args.seconds > 0:
        raise ValueError(f"--seconds must be > 0, got {args.seconds}")
    profile = load_run_profile(args)
    console = ConsoleSink(bar=args.bar, total=args.stacks, quiet=args.quiet)
    service = build_service(profile, args, sinks=[console])
    from edge.runtime.pipeline import pipeline_kind

    coding = " + ".join(x for x in (service.profile.code.name, service.profile.code.source and
                                    f"source {service.profile.code.source}") if x) or "uncoded"
    print(f"edge run: profile {service.profile.name} ({pipeline_kind(service.profile)}, {coding}, "
          f"{service.profile.camera.width}x{service.profile.camera.height} @ {service.profile.camera.rate_hz:g} fps, "
          f"{service.sensor.info.frames_per_stack} frames/stack), sensor {service.sensor.info.name}"
          + ("" if args.no_zenoh else f", zenoh {service.profile.zenoh.key('*')}")
          + (f", ROS 2 via {service.profile.ros.router}" if service.profile.ros.enabled else "")
          + (f", Foxglove ws://127.0.0.1:{args.foxglove}" if getattr(args, "foxglove", None) is not None else "")
          + (f", recording {args.record}" if args.record else ""), flush=True)
    warm_up = getattr(service.pipeline, "warm_up", None)
    if warm_up is not None and not args.quiet:
        print("compiling / loading decoder kernels (about half a minute on the very first run) ...", flush=True)
        print(f"decoder ready in {warm_up():.1f} s", flush=True)
    with stop_on_signals(service.stop) as received:
        status = service.run(stacks=args.stacks, seconds=args.seconds)
    for line in summary_lines(status, console):
        print(line)
    for sink in service.sinks:  # router links of the zenoh sink (edge.io.zenoh_links)
        links = getattr(getattr(sink, "publisher", None), "links", None)
        z = links.stats() if links is not None else None
        if z and (z["disconnects"] or service.profile.zenoh.mode == "client"):
            print(f"zenoh: {z['disconnects']} disconnects, {z['reconnects']} reconnects, "
                  f"{z['disconnected_s']:.1f} s without a router, "
                  f"{z['published_while_disconnected']} depth maps put while disconnected")
    if received:
        print(f"stopped by signal {signal.Signals(received[0]).name}", file=sys.stderr)
    problem = getattr(service.sensor, "problem", None)
    if problem:  # a corrupt or truncated recording behind --sensor replay: not a clean run
        print(f"edge run: error: {problem}", file=sys.stderr)
        return 2
    if status.get("errors") and status["stacks_decoded"] == 0:
        return 1
    return 0

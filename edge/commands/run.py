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
    p.add_argument("--room", metavar="NAME",
                   help="join room NAME: claim a distinct source code from the room's family over zenoh "
                        "(overrides [room] name; see README 'Several devices in one room')")
    p.add_argument("--device", metavar="NAME",
                   help="zenoh key-space device name (overrides [zenoh] device; in a room it is never renamed)")
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
    if getattr(args, "device", None):
        zenoh["device"] = args.device
    update: dict[str, Any] = {"zenoh": zenoh} if zenoh else {}
    if getattr(args, "room", None):
        update["room"] = {"name": args.room}
    if update:
        profile = apply_update(profile, update, source=f"{profile.source} + command line")
    return profile


def join_run_room(profile, args: argparse.Namespace):
    """``edge run --room`` / ``[room] name``: join the room (claim a code) -> `edge.io.room.RoomLink`,
    or None when the profile is not in a room."""
    if not profile.room.name:
        return None
    if getattr(args, "no_zenoh", False):
        raise ValueError("--room needs zenoh to find the other members, got --no-zenoh")
    from edge.io.room import RoomLink

    room = RoomLink(profile, explicit_device=bool(getattr(args, "device", None)))
    print(f"edge run: {room.describe()}", flush=True)
    return room


def build_service(profile, args: argparse.Namespace, *, sinks: list[Any] | None = None, room: Any = None):
    """Sensor, publisher, recorder and `Service` for ``edge run`` arguments (see `register`).

    room: a joined `edge.io.room.RoomLink` (``edge run --room``): the member profile is used, the
    simulated sensors render the other members' light, the publisher shares the room's session and
    the room is the service's last sink (its shutdown leaves the room)."""
    from edge.runtime.service import Service
    from edge.sensors import open_sensor

    if room is not None:
        profile = room.profile
        sinks = list(sinks or []) + [room]  # closed with the sinks if anything below fails
    extra = {"room": room.claim} if room is not None else {}
    try:
        sensor = open_sensor(profile, args.sensor, replay_path=args.replay, max_speed=args.max_speed,
                             poses=args.poses, interference=getattr(args, "interference", False), **extra)
    except BaseException:
        if room is not None:
            room.close()  # leave the room: the code is free again
        raise
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
        if not args.no_zenoh:
            from edge.runtime.publish import ZenohSink

            service.sinks.append(ZenohSink(profile, service, session=room.session if room is not None else None))
        if room is not None:  # the room leaves last (after the publisher that shares its session)
            service.sinks.remove(room)
            service.sinks.append(room)
            room.attach(service)
    except BaseException:
        for s in sinks:
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
    service = build_service(profile, args, sinks=[console], room=join_run_room(profile, args))
    from edge.runtime.pipeline import pipeline_kind

    coding = " + ".join(x for x in (service.profile.code.name, service.profile.code.source and
                                    f"source {service.profile.code.source}") if x) or "uncoded"
    print(f"edge run: profile {service.profile.name} ({pipeline_kind(service.profile)}, {coding}, "
          f"{service.profile.camera.width}x{service.profile.camera.height} @ {service.profile.camera.rate_hz:g} fps, "
          f"{service.sensor.info.frames_per_stack} frames/stack), sensor {service.sensor.info.name}"
          + ("" if args.no_zenoh else f", zenoh {service.profile.zenoh.key('*')}")
          + (f", recording {args.record}" if args.record else ""), flush=True)
    warm_up = getattr(service.pipeline, "warm_up", None)
    if warm_up is not None and not args.quiet:
        print("compiling / loading decoder kernels (about half a minute on the very first run) ...", flush=True)
        print(f"decoder ready in {warm_up():.1f} s", flush=True)
    with stop_on_signals(service.stop) as received:
        status = service.run(stacks=args.stacks, seconds=args.seconds)
    for line in summary_lines(status, console):
        print(line)
    if received:
        print(f"stopped by signal {signal.Signals(received[0]).name}", file=sys.stderr)
    if status.get("errors") and status["stacks_decoded"] == 0:
        return 1
    return 0

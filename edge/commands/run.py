"""``edge run``: the depth service - sensor -> decode -> depth -> zenoh (+ MCAP recording)."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
from typing import Any, Iterator


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "run", help="run the depth service (default: simulated sensor, profile sim-dlp)",
        description="Run the depth service: capture stacks from the sensor, decode them in one thread, "
                    "publish depth/confidence/status over zenoh and optionally record MCAP. "
                    "SIGINT/SIGTERM/SIGHUP stop it cleanly at any moment, also during warm-up (the recording is "
                    "finalised, the summary printed, exit code 0). Exit codes: 0 stopped as asked; 1 the service "
                    "stopped itself on a fault (sensor failure, persistent decode errors) or the recording failed "
                    "(disk full: the file keeps what reached the disk); 2 a start-up error (one line on stderr). "
                    "Under systemd (Type=notify) it sends READY=1 after warm-up, WATCHDOG=1 from the decode loop "
                    "and STOPPING=1; see deploy/systemd/edge.service.")
    p.add_argument("--profile", default="sim-dlp", help="firmware profile name or TOML path (default: sim-dlp)")
    p.add_argument("--sensor", choices=("sim", "replay", "oak", "event"),
                   help="sensor backend (default: the profile's sensor.backend)")
    p.add_argument("--replay", metavar="FILE", help="recording for --sensor replay")
    p.add_argument("--record", metavar="OUT.mcap",
                   help="record raw frames, depth and confidence to MCAP. An existing file is refused unless "
                        "--overwrite; the folder must exist; the file is created only once warm-up is done and "
                        "the sensor started (a failed start-up, or a stop before capture, leaves an existing file "
                        "untouched and creates none)")
    p.add_argument("--overwrite", action="store_true", help="let --record replace an existing recording")
    p.add_argument("--record-max-mb", type=float, metavar="MB",
                   help="rotate: write OUT-<UTC start>-0000.mcap, -0001.mcap... and start the next file when "
                        "one reaches MB megabytes (at a stack boundary; every file is finalised and replays on its "
                        "own; a restart starts a new series, never overwriting)")
    p.add_argument("--record-max-seconds", type=float, metavar="S", help="rotate when a file is S seconds old")
    p.add_argument("--record-keep", type=int, default=0, metavar="N",
                   help="with rotation: keep only the newest N rotated files of OUT (earlier series included), "
                        "deleting older ones, so a long run never fills the disk (default 0: keep all)")
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
                   help=f"stacks waiting for the decoder before the oldest is dropped, 1..{MAX_QUEUE} "
                        "(default 1: freshest); stopping never waits for queued stacks")
    p.add_argument("--bar", action="store_true", help="tqdm progress bar instead of one line per depth map")
    p.add_argument("--quiet", action="store_true", help="only the final summary")
    p.set_defaults(func=run)


#: Largest ``--queue``: more queued stacks only add latency and memory (a stack of the full-size
#: profiles is tens of MB) and a real-time service decodes the freshest one anyway.
MAX_QUEUE = 64
#: Signals that stop the service cleanly.
STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


class StartupError(ValueError):
    """The service cannot start (port taken, no device, unwritable output...): one line, exit code 2."""


@contextlib.contextmanager
def stop_on_signals(stop: Any) -> Iterator[list[int]]:
    """Call ``stop()`` on SIGINT / SIGTERM / SIGHUP while the block runs (main thread only); yields
    the list of signals received.  The handler never raises (no KeyboardInterrupt escapes half-way
    through start-up), so the block's own clean-up always runs; a repeated signal is noted once."""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def handler(signum: int, _frame: Any) -> None:
        received.append(signum)
        if len(received) == 2:
            try:
                os.write(2, b"edge run: already stopping; finishing the recording\n")
            except OSError:
                pass
        stop()

    # an inherited SIG_IGN (nohup for SIGHUP, a background job for SIGINT) is respected
    old = {s: signal.signal(s, handler) for s in STOP_SIGNALS
           if s == signal.SIGTERM or signal.getsignal(s) is not signal.SIG_IGN}
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
    if getattr(args, "device", None):
        zenoh["device"] = args.device
    update: dict[str, Any] = {"zenoh": zenoh} if zenoh else {}
    if getattr(args, "ros", False):
        update["ros"] = {"enabled": True}
    if getattr(args, "room", None):
        update["room"] = {"name": args.room}
    if update:
        profile = apply_update(profile, update, source=f"{profile.source} + command line")
    if profile.ros.enabled and profile.ros.router not in profile.zenoh.connect:
        # ROS mode: connect to the rmw_zenohd router (do not listen on its port)
        profile = apply_update(profile, {"zenoh": {"connect": [*profile.zenoh.connect, profile.ros.router]}},
                               source=profile.source)
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

    Order: sensor, service (decoder), zenoh session; the recording file is opened by `Service.run`
    only after warm-up and ``sensor.start()`` succeeded (``service.recorder_factory``), so a failed
    start-up, or a stop during warm-up, never creates or truncates a file.  Start-up failures raise
    `StartupError`; whatever was opened is closed again.

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
    service = None
    try:
        service = Service(profile, sensor, sinks=sinks, queue_capacity=args.queue)
        zenoh_sink = None
        if not args.no_zenoh:
            zenoh_sink = _zenoh_sink(profile, service, session=room.session if room is not None else None)
            service.sinks.append(zenoh_sink)
        if profile.ros.enabled:
            from edge.io.ros_sink import RosSink

            ros_sink = RosSink(profile, session=zenoh_sink.publisher.session if zenoh_sink else None)
            # before the zenoh sink: it undeclares its entities before that sink closes the shared session
            service.sinks.insert(service.sinks.index(zenoh_sink) if zenoh_sink else len(service.sinks), ros_sink)
        if getattr(args, "foxglove", None) is not None:
            from edge.io.foxglove_sink import FoxgloveSink

            service.sinks.append(FoxgloveSink(profile, port=args.foxglove))
        if room is not None:  # the room leaves last (after the publisher that shares its session)
            service.sinks.remove(room)
            service.sinks.append(room)
            room.attach(service)
        if args.record:
            service.recorder_factory = _recorder_factory(args, profile, sensor)
    except BaseException:
        if service is not None:
            service.close()
        else:
            for s in sinks:
                s.close()
        raise
    return service


def _recorder_factory(args: argparse.Namespace, profile, sensor):
    """Opens the recording; `Service.run` calls it once the sensor started, just before capture."""
    from edge.io.recording import RecordingThread

    mb = getattr(args, "record_max_mb", None)

    def make():
        try:
            return RecordingThread(args.record, profile, sensor_metadata=sensor.info.metadata,
                                   max_bytes=int(mb * 1e6) if mb else None,
                                   max_seconds=getattr(args, "record_max_seconds", None),
                                   keep=getattr(args, "record_keep", 0) or 0)
        except OSError as exc:
            raise StartupError(f"cannot record to {args.record}: {exc.strerror or exc}") from None

    return make


def _zenoh_sink(profile, service, session=None):
    """The zenoh sink, with endpoint checks and one-line errors; warns about unreachable peers."""
    import zenoh

    from edge.io.zenoh_check import check_endpoints, describe_zenoh_error, unreachable
    from edge.io.publish import ZenohSink

    z = profile.zenoh
    try:
        check_endpoints(z)
    except ValueError as exc:
        raise StartupError(str(exc)) from None
    try:
        sink = ZenohSink(profile, service, session=session)
    except zenoh.ZError as exc:
        raise StartupError(describe_zenoh_error(exc, z)) from None
    for endpoint, reason in unreachable(z.connect):
        print(f"edge run: warning: nobody answers on zenoh connect endpoint {endpoint} ({reason}); "
              f"running anyway, zenoh keeps trying in the background", file=sys.stderr, flush=True)
    return sink


def check_run_args(args: argparse.Namespace) -> None:
    """ValueError for out-of-range ``edge run`` options and for a --record target that must not be
    written (see `edge.io.recording.check_record_path`)."""
    if args.stacks is not None and args.stacks < 1:
        raise ValueError(f"--stacks must be >= 1, got {args.stacks}")
    if args.seconds is not None and not args.seconds > 0:
        raise ValueError(f"--seconds must be > 0, got {args.seconds}")
    if not 1 <= args.queue <= MAX_QUEUE:
        raise ValueError(f"--queue must be between 1 and {MAX_QUEUE} stacks, got {args.queue}")
    mb, secs, keep = (getattr(args, k, None) for k in ("record_max_mb", "record_max_seconds", "record_keep"))
    if mb is not None and not (0.01 <= mb <= 1e7):
        raise ValueError(f"--record-max-mb must be between 0.01 and 1e7, got {mb}")
    if secs is not None and not (0.1 <= secs <= 1e7):
        raise ValueError(f"--record-max-seconds must be between 0.1 and 1e7, got {secs}")
    if keep is not None and keep < 0:
        raise ValueError(f"--record-keep must be >= 0, got {keep}")
    rotate = bool(mb or secs)
    if (keep or mb or secs) and not args.record:
        raise ValueError("--record-max-mb / --record-max-seconds / --record-keep need --record")
    if keep and not rotate:
        raise ValueError("--record-keep needs --record-max-mb or --record-max-seconds")
    if args.record:
        from edge.io.recording import check_record_path

        check_record_path(args.record, overwrite=getattr(args, "overwrite", False), rotate=rotate,
                          inputs=(args.replay,))


def run(args: argparse.Namespace) -> int:
    holder: dict[str, Any] = {}

    def stop() -> None:
        service = holder.get("service")
        if service is not None:
            service.stop()

    # signal handlers first: a signal at any later moment (imports, zenoh, warm-up) stops cleanly
    with stop_on_signals(stop) as received:
        check_run_args(args)
        status, console = _run_service(args, holder, received)
    if status is None:  # a signal arrived before the service existed: nothing was opened
        print(f"stopped by signal {signal.Signals(received[0]).name} during start-up", file=sys.stderr)
        return 0
    from edge.runtime.console import summary_lines

    service = holder["service"]
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
    if status.get("fault"):
        print(f"edge run: the service stopped itself: {status['fault']}", file=sys.stderr)
        return 1
    if (status.get("recorder") or {}).get("state") == "stopped":
        return 1
    if status.get("errors") and status["stacks_decoded"] == 0 and not received:
        return 1
    return 0


def _run_service(args: argparse.Namespace, holder: dict[str, Any], received: list[int]):
    from edge.runtime.console import ConsoleSink

    profile = load_run_profile(args)
    backend = args.sensor or profile.sensor.backend
    if args.replay and backend != "replay":  # it was ignored: the simulator ran in its place
        raise ValueError(f"--replay {args.replay}: only the replay sensor reads it, and the sensor is "
                         f"{backend!r}; add --sensor replay")
    if received:
        return None, None
    console = ConsoleSink(bar=args.bar, total=args.stacks, quiet=args.quiet)
    service = build_service(profile, args, sinks=[console], room=join_run_room(profile, args))
    holder["service"] = service
    try:
        if received:
            service.stop()
        from edge.device import pipeline_kind

        coding = " + ".join(x for x in (service.profile.code.name, service.profile.code.source and
                                        f"source {service.profile.code.source}") if x) or "uncoded"
        print(f"edge run: profile {service.profile.name} ({pipeline_kind(service.profile)}, {coding}, "
              f"{service.profile.camera.width}x{service.profile.camera.height} @ {service.profile.camera.rate_hz:g} fps, "
              f"{service.sensor.info.frames_per_stack} frames/stack), sensor {service.sensor.info.name}"
              + ("" if args.no_zenoh else f", zenoh {service.profile.zenoh.key('*')}")
              + (f", ROS 2 via {service.profile.ros.router}" if service.profile.ros.enabled else "")
              + "".join(f", Foxglove ws://127.0.0.1:{sink.port}" for sink in service.sinks  # the bound port (0: any)
                        if type(sink).__name__ == "FoxgloveSink")
              + (f", recording {args.record}" if args.record else ""), flush=True)
        if not args.quiet:
            print("compiling / loading decoder kernels (about two minutes on a 2-core host on the very first run) ...", flush=True)
        if service.warm_up() and not args.quiet:
            print(f"decoder ready in {service.warm_up_s:.1f} s", flush=True)
        status = service.run(stacks=args.stacks, seconds=args.seconds)
    finally:
        service.close()  # zenoh session, recorder: always closed, whatever happened above
    return status, console

"""``edge router --listen ENDPOINT [--connect ROUTER ...]``: an in-process zenoh router.

zenohd (zenoh's router binary) is not on PyPI; a zenoh session in router mode routes the same
protocol, so a site can run one per host or network segment and mesh them with ``--connect``.
Prints one line per router / peer / client that connects or goes away; SIGINT / SIGTERM or
``--seconds`` stop it.
"""

from __future__ import annotations

import argparse
import threading
import time
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "router", help="run an in-process zenoh router (stands in for zenohd) for a mesh of sensors",
        description="Run a zenoh router: sensors (`edge run --mode client --connect ...`) and subscribers "
                    "connect to it; routers connected to each other with --connect form a mesh. Prints "
                    "transport events; stops on SIGINT/SIGTERM or after --seconds.")
    p.add_argument("--listen", action="append", required=True, metavar="ENDPOINT",
                   help="endpoint(s) to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="other router(s) of the mesh (repeatable; retried while they are down)")
    p.add_argument("--seconds", type=float, default=None, metavar="S", help="stop after S seconds")
    p.set_defaults(func=run_router)


def run_router(args: argparse.Namespace) -> int:
    from types import SimpleNamespace

    import zenoh

    from edge.commands.run import stop_on_signals
    from edge.io.zenoh import open_router
    from edge.io.zenoh_check import check_endpoints, describe_zenoh_error

    if args.seconds is not None and not args.seconds > 0:
        raise ValueError(f"expected --seconds > 0, got {args.seconds}")
    check_endpoints(SimpleNamespace(listen=args.listen, connect=args.connect, mode="router"))
    try:
        router = open_router(args.listen, args.connect)
    except zenoh.ZError as exc:  # zenoh's text carries Rust source locations: one plain line instead
        raise ValueError(f"could not start a router on {', '.join(args.listen)}: {describe_zenoh_error(exc)}") from None
    stop = threading.Event()

    def on_event(event: Any) -> None:
        t = event.transport
        what = "connected" if event.kind == zenoh.SampleKind.PUT else "gone"
        print(f"{time.strftime('%H:%M:%S')} {str(t.whatami).split('.')[-1].lower()} {t.zid} {what}", flush=True)

    listener = router.info.declare_transport_events_listener(on_event, history=True) \
        if hasattr(router.info, "declare_transport_events_listener") else None
    print(f"edge router {router.zid()}: listening on {', '.join(args.listen)}"
          + (f", meshed with {', '.join(args.connect)}" if args.connect else ""), flush=True)
    try:
        with stop_on_signals(stop.set):
            stop.wait(args.seconds)
    finally:
        if listener is not None:
            listener.undeclare()
        router.close()
    return 0

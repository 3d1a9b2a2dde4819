"""``edge source``: light-source codes (paper section 5).

    edge source codes [CODE ...] [--family N L] [--kind frame|event]   correlation report
    edge source event-demo [--size 320x240] [--flicker HZ]              event-camera SL metrics
    edge source curtain-demo [--size 320x240]                           light-curtain false/missed rates
"""

from __future__ import annotations

import argparse
import sys
import warnings

from ._args import parse_size

from ..codes.source import PAPER_CODES, correlation_report, family, source_code, worst_interference



#: The options of --table / --room-family where not given (None in the parser, so that giving them
#: without either is refused by name).
ROOM_DEFAULTS = {"stream": "aperiodic", "power_ratio": 1.0, "lengths": "4,6,8,10,12", "max_devices": 16}


def _codes(args: argparse.Namespace) -> int:
    chosen = [name for name, given in (("CODES", args.codes), ("--family", args.family), ("--table", args.table),
                                       ("--room-family", args.room_family)) if given]
    if len(chosen) > 1:  # the report used one of them and ignored the others
        raise ValueError(f"{' and '.join(chosen)}: give one of CODES, --family, --table and --room-family")
    room_only = [name for name, value in (("--stream", args.stream), ("--power-ratio", args.power_ratio),
                                          ("--lengths", args.lengths), ("--max-devices", args.max_devices))
                 if value is not None]
    if args.room_family and (args.lengths is not None or args.max_devices is not None):
        raise ValueError("--lengths / --max-devices: options of --table, not of --room-family")
    if room_only and not (args.table or args.room_family):  # the report ignored them without a word
        raise ValueError(f"{' / '.join(room_only)}: options of --table and --room-family")
    if args.table or args.room_family:
        for name, default in ROOM_DEFAULTS.items():
            if getattr(args, name) is None:
                setattr(args, name, default)
        return _room_codes(args)
    if args.family:
        n, length = args.family
        with warnings.catch_warnings(record=True) as caught:  # the search's stop, as one line
            warnings.simplefilter("always", RuntimeWarning)
            codes = list(family(n, length, args.kind))
        for w in caught:
            print(f"edge source codes: warning: {w.message}", file=sys.stderr)
    else:
        codes = [source_code(c) for c in (args.codes or ["1100", "0101"])]
    print(correlation_report(codes, args.kind))
    worst = max((worst_interference(a, b, kind=args.kind) for a in codes for b in codes if a is not b), default=0.0)
    print(f"worst unsynchronised interference in the set: {worst:.3f} "
          f"(the matched-filter threshold must exceed it)")
    return 0


def _room_codes(args: argparse.Namespace) -> int:
    from ..codes.source_room import MAX_ROOM_LENGTH, format_table, guarantee, margin_table, room_family

    if args.room_family:
        n, length = args.room_family
        fam = room_family(n, length, args.kind, args.stream)
        g = guarantee(fam, power_ratio=args.power_ratio, kind=args.kind, stream=args.stream)
        print(f"room family {n}x{length} ({args.kind}, {args.stream} foreign streams), each foreign device "
              f"<= {args.power_ratio:g} x own:")
        for c, fb, ob, th, m in zip(fam, g.false_bound, g.own_bound, g.threshold, g.margin):
            print(f"  {c.string}  worst foreign sum {fb:+.3f}  worst own {ob:+.3f}  threshold {th:.3f}  margin {m:+.3f}")
        print(f"guaranteed margin {g.guaranteed_margin:+.3f}; largest power ratio with a guarantee "
              f"{g.max_power_ratio:.3f}")
        return 0
    try:
        lengths = tuple(int(v) for v in args.lengths.split(","))
    except ValueError:
        raise ValueError(f"--lengths expects a comma list of code lengths such as 4,6,8, got {args.lengths!r}") from None
    bad = [L for L in lengths if not 2 <= L <= MAX_ROOM_LENGTH]
    if bad:  # the table left such a column out without a word
        raise ValueError(f"--lengths: room families have 2 <= L <= {MAX_ROOM_LENGTH}, got {bad[0]}")
    if args.max_devices < 2:
        raise ValueError(f"--max-devices: the table starts at N = 2 devices, got {args.max_devices}")
    ns = range(2, args.max_devices + 1)
    print(f"kind={args.kind}, stream={args.stream} (exact worst case of the sum of N-1 foreign devices)")
    print(format_table(margin_table(ns, lengths, power_ratio=args.power_ratio, kind=args.kind, stream=args.stream),
                       power_ratio=args.power_ratio))
    return 0


def _event_demo(args: argparse.Namespace) -> int:
    from ..eval.event_sl import run_label, scenarios
    from ..source.event_sl import EventSLConfig

    w, h = parse_size(args.size, minimum=16)
    cfg = EventSLConfig(width=w, height=h, code=args.code, flicker_hz=args.flicker, periods=args.periods)
    print(f"{'run':<28}{'own kept':>9}{'foreign rej':>12}{'flicker rej':>12}{'valid':>7}{'MAE px':>8}{'agree1':>8}")
    for coded, name, _, m in scenarios(cfg):
        label = f"{run_label(cfg, coded)} {name}"
        print(f"{label:<28}{m['own_kept']:>9.3f}{m['interference_rejected']:>12.3f}{m['ambient_rejected']:>12.3f}"
              f"{m['valid']:>7.3f}{m['mae_px']:>8.3f}{m.get('agree1', float('nan')):>8.3f}")
    return 0


def _curtain_demo(args: argparse.Namespace) -> int:
    from ..eval.curtain import run_curtain
    from ..source.curtain import CurtainConfig

    w, h = parse_size(args.size, minimum=16)
    cfg = CurtainConfig(width=w, height=h)
    print(f"{'codes':<30}{'phase':>7}{'false det':>11}{'missed':>9}")
    runs = [(("1", "1"), 0.0), (("1100", "0101"), 0.0), (("1100", "0101"), 1.0), (("1100", "0101"), 2.0)]
    runs += [(tuple(c.string for c in family(3, 6)), (2.0, 3.0))]
    for codes, phase in runs:
        r = run_curtain(cfg, codes, phase_slots=phase).rates()
        print(f"{'/'.join(codes):<30}{str(phase):>7}{r['false_detection_rate']:>11.4f}{r['missed_detection_rate']:>9.4f}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("source", help="light-source codes: families, event SL and light-curtain demos")
    sub = p.add_subparsers(dest="source_command", metavar="ACTION", required=True)
    c = sub.add_parser("codes", help="auto/cross-correlation report of source codes or a searched family",
                       description="One report per call: CODES, --family, --table or --room-family (default: CODES "
                                   "1100 0101). --stream and --power-ratio go with --table and --room-family, "
                                   "--lengths and --max-devices with --table; elsewhere they are refused.")
    c.add_argument("codes", nargs="*", help=f"bit strings or paper names ({', '.join(PAPER_CODES)})")
    c.add_argument("--family", nargs=2, type=int, metavar=("N", "L"), help="search N codes of length L")
    c.add_argument("--kind", choices=("frame", "event"), default="frame",
                   help="camera kind the correlations are for (default frame)")
    c.add_argument("--table", action="store_true",
                   help="N x L table of guaranteed margins under the SUM of N-1 foreign devices "
                        "(room families, no coding, time-division)")
    c.add_argument("--room-family", nargs=2, type=int, metavar=("N", "L"),
                   help="room family of N codes of length L and its exact worst case under the sum")
    c.add_argument("--stream", choices=("aperiodic", "periodic"), default=None,
                   help="--table / --room-family: foreign devices send on/off symbols (aperiodic: DLP, curtains) or repeat their code "
                        f"(periodic: dot projectors) (default {ROOM_DEFAULTS['stream']})")
    c.add_argument("--power-ratio", type=float, default=None, metavar="P",
                   help="--table / --room-family: each foreign device at most P x as bright as the own one "
                        f"(default {ROOM_DEFAULTS['power_ratio']:g})")
    c.add_argument("--lengths", default=None, metavar="L,L,...", help=f"code lengths of --table (default {ROOM_DEFAULTS['lengths']})")
    c.add_argument("--max-devices", type=int, default=None, metavar="N", help=f"largest N of --table (default {ROOM_DEFAULTS['max_devices']})")
    c.set_defaults(func=_codes)
    e = sub.add_parser("event-demo", help="event-camera SL with an interfering dot projector")
    e.add_argument("--size", default="320x240", help="event sensor WxH (default 320x240)")
    e.add_argument("--code", default="10100010", help="own source code, a bit string (default 10100010)")
    e.add_argument("--flicker", type=float, default=0.0, help="ambient flicker frequency (Hz, 0 = none; default 0)")
    e.add_argument("--periods", type=int, default=4, help="code periods simulated (default 4)")
    e.set_defaults(func=_event_demo)
    lc = sub.add_parser("curtain-demo", help="two light curtains with and without source codes")
    lc.add_argument("--size", default="320x240", help="camera WxH (default 320x240)")
    lc.set_defaults(func=_curtain_demo)

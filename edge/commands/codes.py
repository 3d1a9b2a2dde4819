"""``edge codes list|show NAME|table|edc-search``: the code library from the command line.

- ``list``: every listed name with n, k, q, d_min and family.
- ``show NAME``: n, k, d_min, weight distribution, neighbour distances (max / mean) and 0-1
  transitions per frame (``--order binary`` rebuilds a binary linear code in binary column order).
- ``table``: best available d_min per (n, k), k = 6..12, n = k..63, next to the Griesmer bound and
  the published best-known values for k = 10.
- ``edc-search --base xor02-10 --widths 3-6``: every CRC polynomial appended to the base: d_min and
  whether the CRC frames stay high-frequency (widest stripe <= ``--max-stripe`` columns).
"""

from __future__ import annotations

import argparse


from edge.codes import get_code, names
from edge.codes.crc import HIGH_FREQUENCY_STRIPE, edc_search, longest_runs
from edge.codes.linear import from_generator
from edge.codes.table import MAX_N_TABLE, TABLE_N_MAX, table_rows


def _list(args: argparse.Namespace) -> int:
    print(f"{'name':22s} {'n':>3s} {'k':>3s} {'q':>3s} {'d_min':>5s}  family")
    for name in names():
        c = get_code(name)
        print(f"{name:22s} {c.n:3d} {c.k:3d} {c.q:3d} {c.d_min:5d}  {c.family}")
    return 0


def _show(args: argparse.Namespace) -> int:
    code = get_code(args.name)
    if args.order is not None and args.order != code.order:
        if code.q != 2 or not code.systematic or code.generator is None:
            raise ValueError(f"--order applies to systematic binary linear codes; {code.name!r} is not one")
        code = from_generator(code.generator, name=code.name, family=code.family,
                              construction=code.construction, order=args.order)
    nd = code.neighbour_distances()
    wd = code.weight_distribution()
    print(f"name          {code.name}")
    print(f"family        {code.family}")
    print(f"construction  {code.construction}")
    print(f"n, k, q       {code.n}, {code.k}, {code.q}   ({code.size} columns)")
    print(f"d_min         {code.d_min}")
    print(f"systematic    {code.systematic}   linear: {code.is_linear}   column order: {code.order}")
    print("weight distribution (weight: count)")
    print("  " + ", ".join(f"{w}: {c}" for w, c in enumerate(wd) if c))
    print(f"neighbour distance  max {int(nd.max())}  mean {nd.mean():.3f}  min {int(nd.min())}")
    print("per frame        " + " ".join(f"{i:>4d}" for i in range(code.n)))
    print("transitions      " + " ".join(f"{t:>4d}" for t in code.transitions_per_frame()))
    print("widest stripe    " + " ".join(f"{t:>4d}" for t in longest_runs(code.codebook)))
    return 0


def _table(args: argparse.Namespace) -> int:
    if args.k is not None and args.k < 1:
        raise ValueError(f"--k: expected a number of information bits >= 1, got {args.k}")
    ks = range(args.k, args.k + 1) if args.k is not None else range(6, 13)
    if not max(ks) <= args.n_max <= MAX_N_TABLE:  # before the progress bar starts
        raise ValueError(f"--n-max: expected {max(ks)}..{MAX_N_TABLE} (n >= k), got {args.n_max}")
    rows = table_rows(ks, args.n_max, progress=not args.no_progress)
    print(f"{'k':>3s} {'n':>3s} {'d_min':>5s} {'griesmer':>8s} {'known':>6s} {'gap':>4s}  {'family':14s} construction")
    for r in rows:
        known = "-" if r.known is None else (str(r.known[0]) if r.known[0] == r.known[1] else f"{r.known[0]}-{r.known[1]}")
        ref = r.known[1] if r.known else r.griesmer
        print(f"{r.k:3d} {r.n:3d} {r.d_min:5d} {r.griesmer:8d} {known:>6s} {ref - r.d_min:4d}  {r.family:14s} {r.construction}")
    return 0


def _parse_widths(text: str) -> list[int]:
    try:
        if "-" in text:
            lo, hi = (int(t) for t in text.split("-", 1))
            if lo > hi:  # an empty range searched nothing and failed in max()
                raise ValueError
            return list(range(lo, hi + 1))
        return [int(t) for t in text.split(",")]
    except ValueError:
        raise ValueError(f"--widths expects 'LO-HI' (LO <= HI) or a comma list such as '3-6' or '5,6', "
                         f"got {text!r}") from None


def _edc_search(args: argparse.Namespace) -> int:
    base = get_code(args.base)
    if args.max_stripe < 1:
        raise ValueError(f"--max-stripe: expected a number of columns >= 1, got {args.max_stripe}")
    records = edc_search(base, _parse_widths(args.widths), max_stripe=args.max_stripe)
    print(f"base {base.name}: n={base.n}, k={base.k}, d_min={base.d_min}; high-frequency = every CRC frame's "
          f"widest stripe <= {args.max_stripe} columns")
    print(f"{'w':>2s} {'poly':>6s} {'polynomial':24s} {'n':>3s} {'d_min':>5s} {'stripe':>6s} {'trans':>5s}  verdict")
    for r in records if args.all else [r for r in records if r.d_min >= 2]:
        verdict = "high-frequency" if r.high_frequency else "UNFAVOURABLE (low-frequency CRC frame)"
        print(f"{r.width:2d} 0x{r.poly:02x}   {r.polynomial:24s} {r.n:3d} {r.d_min:5d} {r.max_stripe:6d} "
              f"{r.min_transitions:5d}  {verdict}")
    good = [r for r in records if r.high_frequency]
    if good:
        b = good[0]
        print(f"best: CRC-{b.width} 0x{b.poly:02x} ({b.polynomial}): n={b.n}, d_min={b.d_min}, widest CRC stripe {b.max_stripe}")
    else:
        print("best: none of the polynomials keeps every CRC frame high-frequency")
    top_d = max(r.d_min for r in records)
    bad = [r for r in records if not r.high_frequency and r.d_min == top_d]
    print(f"unfavourable: {sum(not r.high_frequency for r in records)} of {len(records)} combinations have a "
          f"low-frequency CRC frame, {len(bad)} of them among those reaching d_min {top_d}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("codes", help="list, show and tabulate structured-light codes")
    sub = parser.add_subparsers(dest="codes_command", metavar="ACTION", required=True)
    p = sub.add_parser("list", help="named codes with n, k, d_min")
    p.set_defaults(func=_list)
    p = sub.add_parser("show", help="properties of one code")
    p.add_argument("name", help="code name, e.g. ecc-22-10 (see 'edge codes list')")
    p.add_argument("--order", choices=("gray", "binary", "gray-plain"), default=None,
                   help="column order for systematic binary linear codes (default: the code's own)")
    p.set_defaults(func=_show)
    p = sub.add_parser("table", help="best d_min per (n, k) next to the Griesmer bound")
    p.add_argument("--k", type=int, default=None, help="only this k (default: 6..12)")
    p.add_argument("--n-max", type=int, default=TABLE_N_MAX, help=f"largest n (default {TABLE_N_MAX})")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_table)
    p = sub.add_parser("edc-search", help="CRC polynomials appended to a base code: d_min and frequency")
    p.add_argument("--base", default="xor02-10", help="base code name (default xor02-10)")
    p.add_argument("--widths", default="3-6", help="CRC widths, 'LO-HI' or comma list within 3..8 (default 3-6)")
    p.add_argument("--max-stripe", type=int, default=HIGH_FREQUENCY_STRIPE,
                   help=f"widest stripe (columns) a high-frequency frame may have (default {HIGH_FREQUENCY_STRIPE})")
    p.add_argument("--all", action="store_true", help="also list polynomials reaching only d_min 1")
    p.set_defaults(func=_edc_search)

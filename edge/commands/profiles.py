"""``edge profiles list|show NAME|check FILE...``: inspect and validate firmware profiles.

- ``list``: one line per profile found on the search path: name, backend, code, description.
- ``show NAME``: the validated settings as JSON (defaults filled in).
- ``check FILE...``: validate each file (or name); prints ``ok`` or the one-line error per file;
  exit 0 when all pass, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json

from edge.profiles import ProfileError, find_profile, list_profiles, load_profile, profile_to_dict


def _list(args: argparse.Namespace) -> int:
    for name in list_profiles():
        try:
            p = load_profile(name)
        except ProfileError as exc:
            print(f"{name:16s} INVALID: {exc}")
            continue
        code = p.code.name or "-"
        if p.code.source:
            code += f" (source {p.code.source})"
        print(f"{name:16s} {p.sensor.backend:7s} {code:28s} {p.description}")
    return 0


def _show(args: argparse.Namespace) -> int:
    p = load_profile(args.name)
    print(f"# {p.source}")
    print(json.dumps(profile_to_dict(p), indent=2))
    return 0


def _check(args: argparse.Namespace) -> int:
    failed = 0
    for item in args.files:
        try:
            path = find_profile(item)
            load_profile(path)
            print(f"ok: {path}")
        except (ProfileError, FileNotFoundError) as exc:
            print(f"error: {exc}")
            failed += 1
        except (ValueError, OSError) as exc:  # anything else still names the file and goes on
            print(f"error: {item}: {type(exc).__name__}: {exc}")
            failed += 1
    return 1 if failed else 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("profiles", help="list, show and check firmware profiles")
    sub = parser.add_subparsers(dest="profiles_command", metavar="ACTION", required=True)
    p_list = sub.add_parser("list", help="profiles on the search path")
    p_list.set_defaults(func=_list)
    p_show = sub.add_parser("show", help="validated settings of one profile as JSON")
    p_show.add_argument("name", help="profile name or TOML path")
    p_show.set_defaults(func=_show)
    p_check = sub.add_parser("check", help="validate profile files")
    p_check.add_argument("files", nargs="+", help="TOML paths or profile names")
    p_check.set_defaults(func=_check)

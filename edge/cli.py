"""The ``edge`` command line.

Every module in ``edge.commands`` that defines ``register(subparsers)`` adds one subcommand; this
file only discovers and dispatches them, so each pipeline stage owns its own command.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from typing import Callable, Sequence

from . import __version__


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="edge",
        description="Depth service for a smart structured-light sensor (redundancy-coded SL).",
    )
    parser.add_argument("--version", action="version", version=f"edge {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    from . import commands

    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    try:  # Ctrl-C while the commands are imported (nothing opened yet): exit 130, no traceback
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        return 130
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        result = args.func(args)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `edge codes list | head`
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Exception as exc:
        message = user_error(exc)
        if message is None:
            raise
        action = getattr(args, f"{args.command}_command", None)  # a group's action: "edge sim record"
        print(f"edge {args.command}{' ' + action if action else ''}: error: {message}", file=sys.stderr)
        return 2
    return int(result or 0)


def tool_main(main: Callable[[], "int | None"], path: str) -> int:
    """Run a ``tools/*.py`` script's ``main()`` as the ``edge`` commands run: bad input and the
    environment (`user_error`) are one ``<script>: error: ...`` line on stderr and exit code 2, Ctrl-C
    is 130; anything else is a bug and raised.  Use: ``raise SystemExit(tool_main(main, __file__))``."""
    try:
        return int(main() or 0)
    except KeyboardInterrupt:
        return 130
    except Exception as exc:
        message = user_error(exc)
        if message is None:
            raise
        print(f"{os.path.basename(path)}: error: {message}", file=sys.stderr)
        return 2


def user_error(exc: BaseException) -> str | None:
    """The one line a command's exception is reported as (exit code 2, no traceback), or None for
    a bug (raised as it is).  Bad input: ValueError (the library's checks); the environment: an
    OSError (a missing, unwritable or full path, a directory where a file goes, a port in use),
    memory, and the errors of zenoh (an endpoint it cannot open: `describe_zenoh_error`) and
    OpenCV (an image it cannot write: its first line)."""
    if isinstance(exc, MemoryError):
        return f"not enough memory ({exc or type(exc).__name__}); try a smaller size"
    if isinstance(exc, OSError):
        return f"{exc.strerror or exc}: {exc.filename}" if exc.filename is not None else str(exc)
    if isinstance(exc, ValueError):
        return str(exc)
    library = type(exc).__module__.split(".")[0]
    if library == "zenoh":
        from .io.zenoh_check import describe_zenoh_error

        return describe_zenoh_error(exc)
    if library == "cv2":
        lines = str(exc).strip().splitlines()
        return lines[0] if lines else type(exc).__name__
    return None


if __name__ == "__main__":
    sys.exit(main())

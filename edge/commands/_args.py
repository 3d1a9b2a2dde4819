"""Argument parsers shared by several subcommands (no ``register``: not a command itself)."""

from __future__ import annotations

import os
from pathlib import Path

from edge.io.paths import check_folder, check_not_folder, write_target


#: Largest width or height a size option takes (pixels): beyond any camera or projector.
MAX_SIZE = 16384


def parse_size(text: str, *, option: str = "--size", minimum: int = 1, maximum: int = MAX_SIZE) -> tuple[int, int]:
    """``'1024x768'`` -> ``(1024, 768)``; ValueError naming the option for anything else, or a
    side outside ``minimum..maximum``."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"{option} expects WIDTHxHEIGHT such as 1024x768, got {text!r}") from None
    if w < minimum or h < minimum:
        raise ValueError(f"{option} must be at least {minimum}x{minimum}, got {text!r}")
    if w > maximum or h > maximum:
        raise ValueError(f"{option} must be at most {maximum}x{maximum}, got {text!r}")
    return w, h


def output_dir(path: str | os.PathLike[str], *, option: str = "--out") -> Path:
    """Create the output folder ``path`` (with its parents) and check it can be written, so a long
    run fails at its start rather than when it writes its results; ValueError naming the option."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} {path}: is a file; expected a folder")
    check_folder(path, option=option, missing_ok=True)  # a file further up: named, not "Not a directory"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{option} {path}: cannot create the folder ({exc.strerror or exc})") from None
    if not os.access(path, os.W_OK):
        raise ValueError(f"{option} {path}: folder is not writable")
    return path


def check_output_file(path: str | os.PathLike[str], *, option: str) -> None:
    """ValueError naming the option unless ``path`` can be written as a file: not a folder, its
    folder exists and is writable (`edge.io.paths.check_folder`: a file where a folder should be is
    named at any depth).  Nothing is created (checked before a long run)."""
    check_not_folder(path, option=option)
    path = Path(path)
    folder = check_folder(Path(write_target(path)).absolute().parent, option=option, path=path)
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise ValueError(f"{option} {path}: not writable")

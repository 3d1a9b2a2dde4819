"""Output locations checked before anything is written: the one wording of "a file stands where a
folder should be" and "the folder does not exist", for every command's outputs.

`check_folder` is used by `edge.io.recording.check_record_path` (recordings) and by
``edge.commands._args`` (``output_dir``, ``check_output_file``), so the same mistake reads the
same through every option: ``OPTION PATH: FILE is a file, not a folder``, with FILE the file found
at any depth of the path (the folder itself, its parent, ...); a file name that is a folder reads
``OPTION PATH: is a folder; expected a file name`` (`check_not_folder`).

Symbolic links are followed as ``open`` follows them: an output that is a link writes the file it
points to and keeps the link (`write_target`, for writers that replace a file by renaming a
finished temporary one onto it), and a broken link where a folder should be is named as one.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["check_folder", "check_not_folder", "file_in_the_way", "write_target"]


def file_in_the_way(folder: str | os.PathLike[str]) -> Path | None:
    """The file standing where ``folder`` or one of the folders above it should be, or None.

    Walks ``folder`` (made absolute), its parent, ... up to the root and stops at the first path
    that exists (a dangling symbolic link counts): that path when it is not a folder, else None
    (``folder`` is a folder, or could be created below an existing one).
    """
    start = Path(os.path.abspath(folder))
    for candidate in (start, *start.parents):
        if os.path.lexists(candidate):
            return None if os.path.isdir(candidate) else candidate
    return None


def check_folder(folder: str | os.PathLike[str], *, option: str, path: str | os.PathLike[str] | None = None,
                 missing_ok: bool = False) -> Path:
    """``folder`` as an absolute Path when it is an existing folder, else ValueError (one line).

    ``option`` and ``path`` (default ``folder``) start the message: the option and the value the
    user gave.  Refused: a file where ``folder`` or a folder above it should be
    (``"OPTION PATH: FILE is a file, not a folder"``), and, unless ``missing_ok`` (the caller
    creates it), a missing folder (``"OPTION PATH: folder FOLDER does not exist"``).  Nothing is
    created or changed.
    """
    label = f"{option} {os.fspath(path if path is not None else folder)}"
    absolute = Path(os.path.abspath(folder))
    blocker = file_in_the_way(absolute)
    if blocker is not None:
        if os.path.islink(blocker) and not os.path.exists(blocker):
            raise ValueError(f"{label}: {blocker} is a broken symbolic link (to {os.readlink(blocker)}), not a folder")
        raise ValueError(f"{label}: {blocker} is a file, not a folder")
    if not missing_ok and not absolute.is_dir():
        raise ValueError(f"{label}: folder {absolute} does not exist")
    return absolute


def check_not_folder(path: str | os.PathLike[str], *, option: str, example: str | None = None) -> None:
    """ValueError ``"OPTION PATH: is a folder; expected a file name"`` (then ``" such as EXAMPLE"``
    where given) when the output file name ``path`` is an existing folder (also through a link)."""
    if os.path.isdir(path):
        such = f" such as {example}" if example else ""
        raise ValueError(f"{option} {os.fspath(path)}: is a folder; expected a file name{such}")


def write_target(path: str | os.PathLike[str]) -> str:
    """The file that writing ``path`` changes: ``path`` itself, or where a symbolic link at
    ``path`` leads (links followed to the end, also a broken one: the file it would create).
    A writer that renames a finished temporary file onto its output renames onto this, next to
    it, so that a link stays a link, as it does for ``open(path, "wb")``."""
    path = os.fspath(path)
    return os.path.realpath(path) if os.path.islink(path) else path

"""Output locations checked before anything is written: the one wording of "a file stands where a
folder should be" and "the folder does not exist", for every command's outputs.

`check_folder` is used by `edge.io.recording.check_record_path` (recordings) and by
``edge.commands._args`` (``output_dir``, ``check_output_file``), so the same mistake reads the
same through every option: ``OPTION PATH: FILE is a file, not a folder``, with FILE the file found
at any depth of the path (the folder itself, its parent, ...).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["check_folder", "file_in_the_way"]


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
        raise ValueError(f"{label}: {blocker} is a file, not a folder")
    if not missing_ok and not absolute.is_dir():
        raise ValueError(f"{label}: folder {absolute} does not exist")
    return absolute

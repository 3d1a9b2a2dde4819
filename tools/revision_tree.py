"""A git revision of this repository checked out beside it, for the A/B tools (`bench_ab.py`,
`bench_compile.py`): one place for the worktree they time side A in."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: The repository root.
HERE = Path(__file__).resolve().parents[1]


@contextmanager
def revision_tree(rev: str, path: Path) -> Iterator[str]:
    """Check `rev` out (detached) into the new folder `path` as a git worktree of this
    repository, yield its short hash, and remove the worktree on exit.  ValueError where `rev`
    is not a revision of this repository."""
    short = subprocess.run(["git", "rev-parse", "--short", rev], cwd=HERE, capture_output=True, text=True)
    if short.returncode != 0:
        raise ValueError(f"--rev {rev!r} is not a revision of this repository")
    subprocess.run(["git", "worktree", "add", "--detach", "-q", str(path), rev], cwd=HERE, check=True)
    try:
        yield short.stdout.strip()
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(path)], cwd=HERE, check=False)

"""Finding and loading firmware-profile TOML files.

Search order for a bare name (``load_profile("sim-dlp")``):

1. each directory in ``$EDGE_PROFILES_PATH`` (``os.pathsep``-separated), if set;
2. ``firmware_profiles/`` at the repository root (source checkouts and ``pip install -e .``);
3. ``<sys.prefix>/share/edge/firmware_profiles/`` (a plain ``pip install .``: pyproject.toml ships
   the files there through ``[tool.setuptools.data-files]``).

A first match wins. Anything that names an existing file, or ends in ``.toml``, is read as a path.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import sysconfig
import tomllib
from pathlib import Path
from typing import Any, Mapping

from .settings import Profile, ProfileError, build_profile, profile_to_dict

__all__ = [
    "DEFAULT_PROFILE",
    "profile_dirs",
    "list_profiles",
    "find_profile",
    "load_profile",
    "profile_from_dict",
    "apply_update",
    "changed_keys",
]

DEFAULT_PROFILE = "sim-dlp"
_ENV = "EDGE_PROFILES_PATH"


def profile_dirs() -> list[Path]:
    """Existing directories searched for ``<name>.toml``, in search order (duplicates removed)."""
    candidates: list[Path] = []
    env = os.environ.get(_ENV, "")
    candidates += [Path(p) for p in env.split(os.pathsep) if p]
    candidates.append(Path(__file__).resolve().parents[2] / "firmware_profiles")
    for prefix in {sys.prefix, sysconfig.get_paths().get("data", sys.prefix)}:
        candidates.append(Path(prefix) / "share" / "edge" / "firmware_profiles")
    seen: set[Path] = set()
    dirs = []
    for d in candidates:
        r = d.resolve()
        if r not in seen and r.is_dir():
            seen.add(r)
            dirs.append(r)
    return dirs


def list_profiles() -> list[str]:
    """Sorted names of the profiles found in `profile_dirs` (file stems)."""
    return sorted({p.stem for d in profile_dirs() for p in d.glob("*.toml")})


def find_profile(name_or_path: str | os.PathLike[str]) -> Path:
    """The TOML file for a profile name or path; FileNotFoundError naming the places searched."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    text = str(name_or_path)
    if path.is_dir():
        raise ValueError(f"profile {text!r} is a folder; expected a TOML file or a profile name")
    if text.endswith(".toml") or os.sep in text or "/" in text:
        raise FileNotFoundError(f"profile file {text!r} does not exist")
    for d in profile_dirs():
        candidate = d / f"{text}.toml"
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(
        f"no profile named {text!r}; known profiles: {', '.join(list_profiles()) or 'none'} "
        f"(searched {', '.join(str(d) for d in profile_dirs()) or 'no directories'})")


def load_profile(name_or_path: str | os.PathLike[str] = DEFAULT_PROFILE) -> Profile:
    """Load and validate a profile by name (see the search order) or path.

    Raises FileNotFoundError if it cannot be found, `ProfileError` (a ValueError) if the TOML is
    malformed or any setting is invalid.
    """
    path = find_profile(name_or_path)
    source = str(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(source, "", f"not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:  # binary or latin-1 files: TOML is UTF-8
        raise ProfileError(source, "", f"not valid TOML: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} "
                                       f"at offset {exc.start})") from None
    except OSError as exc:
        raise ProfileError(source, "", f"cannot read the file: {exc.strerror or exc}") from None
    return build_profile(data, source=source)


def profile_from_dict(data: Mapping[str, Any], source: str = "<dict>") -> Profile:
    """Validate a complete nested dict (e.g. JSON from zenoh) into a `Profile` (same checks as files)."""
    return build_profile(data, source=source)


def _merge(base: dict[str, Any], update: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def apply_update(profile: Profile, update: Mapping[str, Any], source: str = "update") -> Profile:
    """A new profile with ``update`` (a partial nested dict) merged over ``profile``, validated.

    Example: ``apply_update(p, {"decoder": {"method": "hard"}, "edc": {"rounds": 2}})``.
    Unknown keys, wrong types or out-of-range values raise `ProfileError`; ``profile`` is never
    modified (profiles are frozen).
    """
    if not isinstance(update, Mapping):
        raise ProfileError(source, "<root>", f"expected a table (JSON object) of settings, got {type(update).__name__}")
    merged = _merge(profile_to_dict(profile), update)
    return dataclasses.replace(build_profile(merged, source=source), source=source)


def changed_keys(old: Profile, new: Profile) -> list[str]:
    """Dotted keys whose values differ between two profiles (sorted)."""

    def flat(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in d.items():
            key = f"{prefix}{k}"
            if isinstance(v, Mapping):
                out.update(flat(v, key + "."))
            else:
                out[key] = v
        return out

    a, b = flat(profile_to_dict(old)), flat(profile_to_dict(new))
    return sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))

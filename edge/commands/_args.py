"""Argument parsers shared by several subcommands (no ``register``: not a command itself)."""

from __future__ import annotations


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

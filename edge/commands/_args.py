"""Argument parsers shared by several subcommands (no ``register``: not a command itself)."""

from __future__ import annotations


def parse_size(text: str, *, option: str = "--size", minimum: int = 1) -> tuple[int, int]:
    """``'1024x768'`` -> ``(1024, 768)``; ValueError naming the option for anything else."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"{option} expects WIDTHxHEIGHT such as 1024x768, got {text!r}") from None
    if w < minimum or h < minimum:
        raise ValueError(f"{option} must be at least {minimum}x{minimum}, got {text!r}")
    return w, h

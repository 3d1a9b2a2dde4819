"""`--help` of every `edge` command: every option has help text, and an option with a default
says what it is (edge edc run --size said only "camera WxH")."""

from __future__ import annotations

import argparse

from edge.cli import build_parser


def _options(parser: argparse.ArgumentParser, name: str):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, subparser in action.choices.items():
                yield from _options(subparser, f"{name} {sub}")
        elif not isinstance(action, (argparse._HelpAction, argparse._VersionAction)):
            yield name, action


def test_every_option_has_help_that_states_its_default():
    missing, undocumented = [], []
    for name, action in _options(build_parser(), "edge"):
        label = f"{name} {'/'.join(action.option_strings) or action.dest}"
        if not action.help:
            missing.append(label)
            continue
        default = action.default
        if default in (None, False, [], argparse.SUPPRESS) or isinstance(default, bool):
            continue
        if "default" not in action.help and str(default) not in action.help:
            undocumented.append(f"{label} (default {default!r})")
    assert not missing, missing
    assert not undocumented, undocumented

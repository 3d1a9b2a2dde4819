"""tools/*.py on bad input: one `<script>: error: ...` line and exit code 2 as the `edge` commands
(`edge.cli.tool_main`), no traceback; `--help` on every script."""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from edge.cli import tool_main

TOOLS = Path(__file__).resolve().parents[1] / "tools"


def _tool(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run([sys.executable, str(TOOLS / argv[0]), *argv[1:]], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=300)


@pytest.mark.parametrize("argv, expect", [
    (("eval_nary.py", "--size", "abc"), "eval_nary.py: error: --size expects WIDTHxHEIGHT"),  # int()'s traceback
    (("eval_posterior.py", "--size", "64", "--out", "p"), "eval_posterior.py: error: --size expects"),
    (("eval_per_pixel_limit.py", "--atoms", "0", "--out", "l.md"), "eval_per_pixel_limit.py: error: --atoms must be"),
    (("eval_sgm_error.py", "--ambient", "0", "--out", "s"), "eval_sgm_error.py: error: --ambient: expected positive"),
    (("eval_room.py", "--max-devices", "0", "--out", "r"), "eval_room.py: error: --max-devices must be >= 2"),  # IndexError
    (("eval_edc.py", "--width", "4", "--height", "4", "--out", "e"), "eval_edc.py: error: camera 4x4 is too small"),
    (("eval_sweep.py", "--experiments", "bogus", "--out", "s"), "eval_sweep.py: error: unknown experiment 'bogus'"),
    (("foxglove_layout.py", "--out", "missing/layout.json"), "foxglove_layout.py: error: No such file or directory"),
    (("bench_replay_fleet.py", "--files", "0"), "bench_replay_fleet.py: error: --files must be >= 1"),  # IndexError
    (("bench_mcap_encoding.py", "--frames", "0"), "bench_mcap_encoding.py: error: --frames and --repeats"),  # IndexError
    (("bench_outputs.py", "--repeats", "1"), "bench_outputs.py: error: expected --repeats >= 3"),  # exit 1
    (("bench_code_search.py", "--pairs", "5y3"), "bench_code_search.py: error: argument --pairs"),  # exit 1
    (("bench_ab.py", "--cases", "real", "--real", "missing"), "bench_ab.py: error: --real: missing is not a folder"),
    (("bench_ab.py", "--rev", "no-such-rev"), "bench_ab.py: error: --rev 'no-such-rev' is not a revision"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, argv, expect):
    r = _tool(*argv, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and r.stderr.strip().splitlines()[-1].startswith(expect), r.stderr
    assert not any(tmp_path.iterdir())  # refused before any output was written


def test_check_codes_galois_has_help(tmp_path):
    """It ran the whole check on --help (it had no argument parser)."""
    pytest.importorskip("galois")
    r = _tool("check_codes_galois.py", "--help", cwd=tmp_path)
    assert r.returncode == 0 and r.stdout.startswith("usage: check_codes_galois.py") and "BCH(" not in r.stdout


def test_tool_main_reports_input_errors_and_raises_bugs(capsys):
    def bad_input() -> int:
        raise ValueError("--size expects WIDTHxHEIGHT")

    def bug() -> int:
        raise KeyError("x")

    assert tool_main(bad_input, "/x/tools/eval_demo.py") == 2
    assert capsys.readouterr().err == "eval_demo.py: error: --size expects WIDTHxHEIGHT\n"
    assert tool_main(lambda: None, "t.py") == 0 and tool_main(lambda: 1, "t.py") == 1
    with pytest.raises(KeyError):
        tool_main(bug, "t.py")


class _Parsed(Exception):
    """Raised instead of parsing: carries the script's parser out of its ``main``."""


def _tool_parser(script: Path, monkeypatch) -> argparse.ArgumentParser | None:
    """The argument parser ``script``'s ``main`` builds (None for a script without ``main``): the
    script is imported and ``main`` stopped at its ``parse_args`` call, before any work."""
    def stop(self, *_a, **_k):
        raise _Parsed(self)

    name = f"_tool_{script.stem}"
    spec = importlib.util.spec_from_file_location(name, script)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, module)  # dataclasses look their module up there
    spec.loader.exec_module(module)
    if not hasattr(module, "main"):
        return None
    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", stop)
    with pytest.raises(_Parsed) as parsed:
        module.main()
    monkeypatch.undo()
    return parsed.value.args[0]


def _renderings(default) -> set[str] | None:
    """How a help text may write ``default`` ("default 0.5", "default 0 1", "default docs/x"), or
    None when no generic rendering exists (the word "default" must do)."""
    if isinstance(default, (list, tuple)):
        if not all(isinstance(v, (str, int, float)) for v in default):
            return None
        return {" ".join(map(str, default)), ",".join(map(str, default)), ", ".join(map(str, default))}
    out = {str(default)}
    if isinstance(default, float):
        out.add(f"{default:g}")
    if isinstance(default, (str, os.PathLike)) and os.path.isabs(default):
        out.add(os.path.relpath(default, TOOLS.parent))  # a path below the repository, written from its root
    return out


def test_every_tool_option_states_its_default(monkeypatch):
    """As `edge`'s own options (tests/test_cli_help.py): an option with a default says which, in
    argparse's ``%(default)s`` (or ``%(default)g``) or in words that name the real value (store_true flags and options
    without a default excepted).  bench_service --seconds, eval_room --pixels and more did not."""
    undocumented, parsers = [], 0
    for script in sorted(TOOLS.glob("*.py")):
        parser = _tool_parser(script, monkeypatch)
        if parser is None:
            assert "add_argument" not in script.read_text(), f"{script.name}: options but no main()"
            continue
        parsers += 1
        for action in parser._actions:
            default = action.default
            if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS \
                    or default in (None, False, [], argparse.SUPPRESS) or isinstance(default, bool):
                continue
            text = action.help or ""
            label = f"{script.name} {'/'.join(action.option_strings) or action.dest} (default {default!r})"
            if "%(default)" in text:  # argparse writes the real value
                continue
            shown = _renderings(default)
            if "default" not in text or (shown is not None and not any(s in text for s in shown)):
                undocumented.append(f"{label}: {text!r}")
    assert parsers >= 25
    assert not undocumented, "\n".join(undocumented)

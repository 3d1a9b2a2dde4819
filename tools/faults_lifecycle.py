"""Fault trials of the service's life: signals at points over its life, start-up errors, a full disk,
SIGKILL salvage.  Used by tests/faults/ (a few trials, CI) and tools/fault_report.py (``--full``).

Each trial runs ``edge run`` (real sim sensor, real zenoh on a free loopback port, real numba
kernels, real MCAP file) in a subprocess, stops it the way a user or systemd would, and checks:
exit code and time to exit; the summary printed; the recording readable with the ``mcap`` reader
with CRCs validated; every frame the service captured is in the file (``frames_lost`` 0 and the
file's raw-frame count equal to ``frames_written``).

    python tools/faults_lifecycle.py [--full]      # prints the rows as a table
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from _service_helpers import interactive_signals  # noqa: E402
from _ports import free_port  # noqa: E402
TEST_PROFILE = ROOT / "tests" / "data" / "profiles" / "test-small.toml"
#: a stopped service must be gone within this many seconds of the (first) signal
EXIT_BOUND_S = 20.0


def env_for(cache_dir: str | None = None, **extra: str) -> dict[str, str]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    env.update(extra)
    return env


class Proc:
    """``edge run`` in a subprocess with its output collected line by line (stdout + stderr)."""

    def __init__(self, args: list[str], *, env: dict[str, str] | None = None, cwd: str | None = None,
                 command: list[str] | None = None) -> None:
        self.started = time.monotonic()
        argv = command if command is not None else [sys.executable, "-m", "edge.cli", *map(str, args)]
        self.p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                  env=env or env_for(), cwd=cwd, preexec_fn=interactive_signals)
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.p.stdout:
            with self._cond:
                self.lines.append(line.rstrip("\n"))
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def wait_for(self, pattern: str, count: int = 1, timeout: float = 600.0) -> bool:
        """Wait until ``count`` output lines match ``pattern`` (regex); False on timeout or exit."""
        rx = re.compile(pattern)
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                if sum(1 for line in self.lines if rx.search(line)) >= count:
                    return True
                if self.p.poll() is not None and not self._reader.is_alive():
                    return False
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(min(left, 0.05))

    def signal(self, sig: int) -> float:
        t = time.monotonic()
        self.p.send_signal(sig)
        return t

    def finish(self, timeout: float = EXIT_BOUND_S) -> tuple[int | None, float]:
        """(exit code or None if it had to be killed, seconds from now to exit)."""
        t0 = time.monotonic()
        try:
            rc = self.p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.p.wait()
            rc = None
        self._reader.join(5)
        return rc, time.monotonic() - t0

    @property
    def output(self) -> str:
        with self._cond:
            return "\n".join(self.lines)


def summary_value(output: str, key: str) -> int | None:
    m = re.search(rf"\b{key} (\d+)", output)
    return int(m.group(1)) if m else None


def check_recording(path: Path) -> dict[str, Any]:
    """Read ``path`` with the mcap reader (CRCs validated): readable, raw frames, depth maps."""
    from mcap.reader import make_reader

    out: dict[str, Any] = {"exists": path.exists(), "readable": False, "raw": 0, "depth": 0, "error": ""}
    if not path.exists():
        return out
    try:
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
            if summary is None:
                raise ValueError("no summary (not finalised)")
            for _schema, channel, _msg in reader.iter_messages():
                if channel.topic.endswith("/raw"):
                    out["raw"] += 1
                elif channel.topic.endswith("/depth"):
                    out["depth"] += 1
        out["readable"] = True
    except Exception as exc:  # the outcome, not a crash of the trial
        out["error"] = f"{type(exc).__name__}: {exc}"
    return out


@dataclass
class SignalTrial:
    """One signal at one point of the service's life."""

    point: str                  # import | warm-up | first-stack | steady | config-change | shutdown | quiet-warm-up
    sig: int = signal.SIGTERM
    cold: bool = False          # empty numba cache (first start on a device)
    delay_s: float = 0.0        # extra wait after the point is reached
    result: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return (f"{signal.Signals(self.sig).name} at {self.point}"
                + (f" +{self.delay_s:g}s" if self.delay_s else "") + (" (cold cache)" if self.cold else ""))


def run_signal_trial(trial: SignalTrial, workdir: Path, *, cache_dir: str | None = None) -> dict[str, Any]:
    """Run one `SignalTrial`; returns the result dict (also stored in ``trial.result``)."""
    workdir.mkdir(parents=True, exist_ok=True)
    out = workdir / "run.mcap"
    if out.exists():
        out.unlink()
    cold_dir = tempfile.mkdtemp(prefix="numba-cold-", dir=workdir) if trial.cold else None
    port = free_port()
    args = ["run", "--profile", TEST_PROFILE, "--record", out, "--seconds", "600", "--listen",
            f"tcp/127.0.0.1:{port}"]
    if trial.point == "quiet-warm-up":
        args.append("--quiet")
    proc = Proc(args, env=env_for(cold_dir or cache_dir), cwd=str(workdir))
    reached = True
    if trial.point == "import":
        time.sleep(0.3 + trial.delay_s)
    elif trial.point in ("warm-up", "quiet-warm-up"):
        reached = proc.wait_for(r"^edge run: profile", timeout=120)
        time.sleep(trial.delay_s)
    elif trial.point == "first-stack":
        reached = proc.wait_for(r"^stack +\d+:", timeout=900)
        time.sleep(trial.delay_s)
    elif trial.point in ("steady", "shutdown"):
        reached = proc.wait_for(r"^stack +\d+:", count=3, timeout=900)
        time.sleep(trial.delay_s)
    elif trial.point == "config-change":
        reached = proc.wait_for(r"^stack +\d+:", count=2, timeout=900)
        if reached:
            _config_change(port, trial.delay_s)
    proc.signal(trial.sig)
    if trial.point == "shutdown":  # a second signal while it finalises
        time.sleep(0.05)
        if proc.p.poll() is None:
            proc.signal(trial.sig)
    rc, exit_s = proc.finish()
    text = proc.output
    rec = check_recording(out)
    written, lost = summary_value(text, "frames_written"), summary_value(text, "frames_lost")
    captured_any = bool(written)
    res = {
        "trial": trial.name, "reached": reached, "rc": rc, "exit_s": round(exit_s, 2),
        "summary": "fps " in text and "stacks: complete" in text,
        "traceback": "Traceback" in text, "file": rec, "frames_written": written, "frames_lost": lost,
    }
    # an unreadable file: a file exists that the mcap reader rejects
    res["unreadable"] = rec["exists"] and not rec["readable"]
    # complete frames lost: frames the service captured that are not in the file
    res["frames_missing"] = (lost or 0) + max(0, (written or 0) - rec["raw"]) if captured_any else 0
    # before `edge run` installed its handlers (Python still importing, nothing opened): SIGINT
    # exits 130, SIGTERM / SIGHUP end the process by the signal; afterwards always 0
    early = trial.point == "import" and not rec["exists"] and rc in (130, -trial.sig)
    res["early"] = early and rc != 0
    res["ok"] = ((rc == 0 or early) and not res["traceback"] and not res["unreadable"] and res["frames_missing"] == 0
                 and (res["summary"] or trial.point == "import"))
    res["output_tail"] = text[-1500:]
    trial.result = res
    return res


def _config_change(port: int, delay_s: float) -> None:
    """Ask the running service (over zenoh) to switch decoder method, then return after ``delay_s``."""
    import json

    import zenoh

    from edge.io.zenoh import make_config

    with zenoh.open(make_config(connect=[f"tcp/127.0.0.1:{port}"])) as s:
        replies = list(s.get("sl/test-small/config", payload=json.dumps({"decoder": {"method": "hard"}}).encode(),
                             timeout=5.0))
        assert replies, "no reply from the config queryable"
    time.sleep(delay_s)


#: the CI subset (tests/faults): a few points, warm cache
CI_TRIALS = [
    # +0.5 s: inside edge's own imports (before that, Python itself is still starting up and a
    # Ctrl-C is its own KeyboardInterrupt traceback, which no code of ours can intercept)
    SignalTrial("import", signal.SIGINT, delay_s=0.5),
    SignalTrial("warm-up", signal.SIGTERM),
    SignalTrial("shutdown", signal.SIGHUP),   # steady state, then a second signal while it finalises
]


def full_trials() -> list[SignalTrial]:
    """>= 20 distinct moments over the service's life (warm and cold numba cache), the three stop
    signals in turn, and a second signal during shutdown."""
    moments = [("import", 0.0), ("import", 0.5), ("import", 1.0),
               ("warm-up", 0.0), ("warm-up", 0.3), ("warm-up", 1.0), ("quiet-warm-up", 0.5),
               ("first-stack", 0.0), ("first-stack", 0.1),
               ("steady", 0.0), ("steady", 0.5), ("steady", 1.0), ("steady", 2.0),
               ("config-change", 0.0), ("config-change", 0.1), ("config-change", 0.3), ("config-change", 1.0),
               ("shutdown", 0.0)]
    cold = [("warm-up", 1.0), ("warm-up", 2.0), ("warm-up", 5.0), ("warm-up", 10.0), ("warm-up", 15.0),
            ("quiet-warm-up", 5.0)]
    sigs = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    t = [SignalTrial(p, sigs[i % 3], delay_s=d) for i, (p, d) in enumerate(moments)]
    t += [SignalTrial(p, sigs[(i + 1) % 3], cold=True, delay_s=d) for i, (p, d) in enumerate(cold)]
    t += [SignalTrial("shutdown", signal.SIGINT), SignalTrial("steady", signal.SIGTERM, delay_s=3.0)]
    return t


def sigkill_trial(workdir: Path) -> dict[str, Any]:
    """SIGKILL at steady state; ``edge replay --recover`` must salvage the complete chunks."""
    workdir.mkdir(parents=True, exist_ok=True)
    out, rec = workdir / "killed.mcap", workdir / "killed.recovered.mcap"
    for p in (out, rec):
        if p.exists():
            p.unlink()
    small = workdir / "test-small-64k.toml"
    small.write_text(TEST_PROFILE.read_text().replace("chunk_size = 4194304", "chunk_size = 65536"))
    proc = Proc(["run", "--profile", small, "--record", out, "--seconds", "600", "--no-zenoh"], cwd=str(workdir))
    reached = proc.wait_for(r"^stack +\d+:", count=2, timeout=900)
    time.sleep(0.5)
    proc.signal(signal.SIGKILL)
    proc.finish()
    r = subprocess.run([sys.executable, "-m", "edge.cli", "replay", str(out), "--recover"], capture_output=True,
                       text=True, env=env_for(), timeout=600)
    salvaged = check_recording(rec)
    return {"reached": reached, "rc": r.returncode, "salvaged": salvaged, "traceback": "Traceback" in r.stderr,
            "ok": reached and salvaged["readable"] and salvaged["raw"] > 0 and "Traceback" not in r.stderr,
            "output": (r.stdout + r.stderr)[-800:]}


def full_disk_trial(workdir: Path, limit_bytes: int = 1_500_000, stacks: int = 40) -> dict[str, Any]:
    """``edge run --record`` with the file size limited (RLIMIT_FSIZE, EFBIG like a full disk)."""
    import resource

    workdir.mkdir(parents=True, exist_ok=True)
    out = workdir / "full.mcap"
    if out.exists():
        out.unlink()
    small = workdir / "test-small-64k.toml"
    small.write_text(TEST_PROFILE.read_text().replace("chunk_size = 4194304", "chunk_size = 65536"))

    def limit() -> None:
        interactive_signals()
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)   # write() fails with EFBIG instead of killing
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    proc = subprocess.Popen([sys.executable, "-m", "edge.cli", "run", "--profile", str(small), "--record", str(out),
                             "--stacks", str(stacks), "--no-zenoh", "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=env_for(), cwd=str(workdir), preexec_fn=limit)
    text, _ = proc.communicate(timeout=900)
    rec = check_recording(out)
    written = summary_value(text, "frames_written")
    decoded = re.search(r"decoded (\d+)", text)
    res = {"rc": proc.returncode, "traceback": "Traceback" in text, "file": rec, "frames_written": written,
           "frames_lost": summary_value(text, "frames_lost"), "stacks_decoded": int(decoded.group(1)) if decoded else 0,
           "state_stopped": "state stopped" in text, "error_named": "File too large" in text,
           "size": out.stat().st_size if out.exists() else 0, "output_tail": text[-1500:]}
    res["ok"] = (rec["readable"] and written == rec["raw"] and not res["traceback"] and res["state_stopped"]
                 and res["error_named"] and res["stacks_decoded"] == stacks and res["size"] <= limit_bytes)
    return res


#: a port held by `hold_port` while the start-up cases run (the "port taken" case)
HELD_PORT = [0]


def hold_port() -> socket.socket:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    HELD_PORT[0] = s.getsockname()[1]
    return s


def startup_error_cases(tmp: Path) -> list[tuple[str, list[str], str]]:
    """(name, edge arguments, expected text in the one-line error) for start-up faults that need no
    port held open; `held_port_case` covers a taken port."""
    tmp.mkdir(parents=True, exist_ok=True)
    existing = tmp / "existing.mcap"
    existing.write_bytes(b"keep me")
    client = tmp / "test-small-client.toml"
    client.write_text(TEST_PROFILE.read_text().replace('mode = "peer"', 'mode = "client"')
                      .replace("connect = []", f'connect = ["tcp/127.0.0.1:{free_port()}"]'))
    base = ["run", "--profile", str(TEST_PROFILE), "--stacks", "1"]
    return [
        ("no OAK device", base + ["--sensor", "oak", "--no-zenoh"], "no OAK device"),
        ("duplicate --listen", base + ["--listen", "tcp/127.0.0.1:7461", "--listen", "tcp/127.0.0.1:7461"], "twice"),
        ("non-local listen address", base + ["--listen", "tcp/192.0.2.1:7461"], "not one of this host"),
        ("client mode, nobody to connect to", ["run", "--profile", str(client), "--stacks", "1"], "Unable to connect"),
        ("port taken", base + ["--listen", f"tcp/127.0.0.1:{HELD_PORT[0]}"], "already in use"),
        ("--record is a folder", base + ["--no-zenoh", "--record", str(tmp)], "is a folder; expected a file name"),
        ("--record in a missing folder", base + ["--no-zenoh", "--record", str(tmp / "nope" / "a.mcap")], "does not exist"),
        ("--record in a read-only folder", base + ["--no-zenoh", "--record", "/proc/sys/edge-test.mcap"], "not writable"),
        ("--record /dev/full", base + ["--no-zenoh", "--record", "/dev/full", "--overwrite"], "not a regular file"),
        ("--record name too long", base + ["--no-zenoh", "--record", str(tmp / ("x" * 300 + ".mcap"))], "longer than"),
        ("--record existing file", base + ["--no-zenoh", "--record", str(existing)], "already exists"),
        ("--queue 1000000", base + ["--no-zenoh", "--queue", "1000000"], "--queue"),
    ]


def run_startup_case(args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "edge.cli", *args], capture_output=True, text=True, env=env_for(),
                          timeout=300)


def startup_error_ok(r: subprocess.CompletedProcess, expect: str | None) -> bool:
    """Exit 2, exactly one ``edge run: error`` line (containing ``expect``), no traceback."""
    lines = [x for x in r.stderr.splitlines() if x.startswith("edge run: error")]
    return (r.returncode == 2 and len(lines) == 1 and "Traceback" not in r.stderr
            and (expect is None or expect in lines[0]))


def rows(full: bool) -> list[dict[str, Any]]:
    """Rows of tools/fault_report.py: fault | trials | outcomes | target | met."""
    import shutil

    work = Path(tempfile.mkdtemp(prefix="edge-faults-lifecycle-"))
    try:
        return _rows(full, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _rows(full: bool, work: Path) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    trials = full_trials() if full else CI_TRIALS
    results = [run_signal_trial(t, work / f"sig{i}") for i, t in enumerate(trials)]
    n_cold = sum(t.cold for t in trials)
    bad_rc = [r for r in results if r["rc"] != 0 and not r["early"]]
    early = sum(r["early"] for r in results)
    failed = [r["trial"] for r in results if not r["ok"]]
    unreadable = sum(r["unreadable"] for r in results)
    missing = sum(r["frames_missing"] for r in results)
    slow = max(r["exit_s"] for r in results)
    moments = len({(t.point, t.delay_s, t.cold) for t in trials})
    points = ", ".join(dict.fromkeys(t.point for t in trials))
    sigs = "/".join(dict.fromkeys(signal.Signals(t.sig).name for t in trials))
    out.append({"fault": f"signals at {moments} moments of the service's life ({points}; {sigs}; "
                         f"{n_cold} with a cold numba cache)",
                "trials": len(results),
                "outcomes": f"{unreadable} unreadable files, {missing} complete frames lost, "
                            f"{len(bad_rc)} unexpected exit codes (exit 0: {sum(r['rc'] == 0 for r in results)}, "
                            f"130/143 before the handlers, nothing opened: {early}), "
                            f"{sum(r['traceback'] for r in results)} tracebacks, slowest exit {slow:.1f} s"
                            + (f"; failed: {', '.join(failed)}" if failed else ""),
                "target": f"0 / 0 / 0 / 0, exit < {EXIT_BOUND_S:g} s",
                "met": unreadable == 0 and missing == 0 and not bad_rc and slow < EXIT_BOUND_S and not failed
                and not any(r["traceback"] for r in results)})
    k = sigkill_trial(work / "kill")
    out.append({"fault": "SIGKILL at steady state, then edge replay --recover", "trials": 1,
                "outcomes": f"{k['salvaged']['raw']} raw frames, {k['salvaged']['depth']} depth maps salvaged "
                            f"(CRC-valid: {k['salvaged']['readable']})",
                "target": "salvaged file readable, > 0 frames", "met": k["ok"]})
    d = full_disk_trial(work / "disk")
    out.append({"fault": "disk full while recording (RLIMIT_FSIZE 1.5 MB, EFBIG)", "trials": 1,
                "outcomes": f"stacks decoded {d['stacks_decoded']}/40, frames_written {d['frames_written']} = "
                            f"{d['file']['raw']} in the file, finalised: {d['file']['readable']}, "
                            f"status stopped: {d['state_stopped']}, tracebacks {int(d['traceback'])}",
                "target": "keeps publishing, honest counts, finalised file, no traceback", "met": d["ok"]})
    held = hold_port()
    try:
        cases = startup_error_cases(work / "startup")
        clean = sum(startup_error_ok(run_startup_case(args), expect) for _name, args, expect in cases)
    finally:
        held.close()
    out.append({"fault": "start-up errors (no device, zenoh endpoints, unwritable/existing --record, --queue)",
                "trials": len(cases), "outcomes": f"{clean} one-line errors with exit 2, {len(cases) - clean} other",
                "target": "all one line, exit 2", "met": clean == len(cases)})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--full", action="store_true", help=">= 20 signal points, warm and cold numba cache")
    args = ap.parse_args()
    for row in rows(args.full):
        print(" | ".join(str(row[k]) for k in ("fault", "trials", "outcomes", "target", "met")))


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))

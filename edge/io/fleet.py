"""Replay many recordings on Ray (``pip install 'edge[fleet]'``): one task per recording.

`replay_on_ray(paths, workers=N)` starts a local Ray instance with ``num_cpus=N`` (or joins the
cluster at ``address``), runs `edge.io.replay_many.replay_one` as one task per file (1 CPU
each) and returns the `FileResult` list in input order.  A task that dies (worker crash, out of
memory) becomes that file's ``error``; the other files go on.

Workers get ``NUMBA_CACHE_DIR`` (the driver's, when set) through ``runtime_env`` ``env_vars`` so
they load the decoder kernels the driver compiled instead of compiling their own, and, on a
local instance, ``NUMBA_NUM_THREADS = cores // N`` so N workers do not oversubscribe the cores
(the decoder kernels are numba-parallel), and ``PYTHONPATH`` with this edge package's parent
directory.  On a cluster, every node needs edge and its dependencies installed (same version)
and the recordings at the same paths (shared storage): tasks get paths, not file contents.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from typing import Any, Callable, Sequence

from .replay_many import FileResult, replay_one

__all__ = ["require_ray", "replay_on_ray"]

INSTALL_HINT = "pip install 'edge[fleet]'"


def require_ray(what: str = "--workers > 1"):
    """The ``ray`` module, or ValueError telling the user to install the fleet extra."""
    try:
        import ray
    except ImportError:
        raise ValueError(f"{what} runs the replays on Ray, which is not installed: {INSTALL_HINT}") from None
    return ray


def worker_env(workers: int, *, local: bool) -> dict[str, str]:
    """``runtime_env`` ``env_vars`` for the replay workers (see module docstring)."""
    env: dict[str, str] = {}
    if os.environ.get("NUMBA_CACHE_DIR"):
        env["NUMBA_CACHE_DIR"] = os.path.abspath(os.environ["NUMBA_CACHE_DIR"])
    if local:
        import edge

        env["NUMBA_NUM_THREADS"] = str(max(1, (os.cpu_count() or 1) // max(1, workers)))
        root = os.path.dirname(os.path.dirname(os.path.abspath(edge.__file__)))
        env["PYTHONPATH"] = os.pathsep.join([root] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
                                                      if p and p != root])
    return env


def check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """ValueError when ``host:port`` (or ``ray://host:port``) does not accept a TCP connection within
    ``timeout_s`` (``ray.init`` would retry such an address for minutes). ``auto`` is left to Ray."""
    import socket

    target = address[len("ray://"):] if address.startswith("ray://") else address
    host, sep, port = target.rpartition(":")
    if not sep or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise ValueError(f"no Ray cluster answers at {address} ({exc.strerror or exc})") from None


def _task(path: str, expected_profile: Any) -> dict[str, Any]:
    return replay_one(path, expected_profile).as_dict()


def replay_on_ray(paths: Sequence[str], *, workers: int, address: str | None = None,
                  expected_profile: Any = None,
                  on_done: Callable[[FileResult], None] | None = None,
                  timings: dict[str, float] | None = None) -> list[FileResult]:
    """Replay ``paths`` as Ray tasks (see module docstring); ``on_done`` is called per finished file;
    ``timings["startup_s"]`` gets the seconds ``ray.init`` took (0 if Ray was already running) and
    ``timings["cpus"]`` the cluster's CPUs (= the number of files replayed at once)."""
    ray = require_ray("--workers > 1" if address is None else "--address")
    if workers < 1:
        raise ValueError(f"expected --workers >= 1, got {workers}")
    local = address is None
    started_here = not ray.is_initialized()
    t0 = time.perf_counter()
    main = threading.current_thread() is threading.main_thread()
    old_sigterm = signal.getsignal(signal.SIGTERM) if main else None  # ray.init replaces it
    if started_here:
        kwargs: dict[str, Any] = dict(runtime_env={"env_vars": worker_env(workers, local=local)},
                                      logging_level="ERROR", log_to_driver=False)
        if local:
            kwargs.update(num_cpus=workers, include_dashboard=False,
                          object_store_memory=128 * 1024 * 1024)  # results are small dicts
        else:
            check_reachable(address)
            kwargs.update(address=address)
        try:
            ray.init(**kwargs)
        except Exception as exc:  # cluster not reachable, ...
            if old_sigterm is not None:
                signal.signal(signal.SIGTERM, old_sigterm)
            raise ValueError(f"could not start Ray{'' if local else f' at {address}'}: "
                             f"{type(exc).__name__}: {exc}") from None
    if timings is not None:
        timings["startup_s"] = time.perf_counter() - t0
        timings["cpus"] = float(ray.cluster_resources().get("CPU", 0.0))
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(_task)
        refs = {task.remote(p, expected_profile): i for i, p in enumerate(paths)}
        results: list[FileResult | None] = [None] * len(paths)
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                i = refs[ref]
                try:
                    results[i] = FileResult(**ray.get(ref))
                except Exception as exc:  # the task itself died
                    results[i] = FileResult(path=paths[i], error=f"Ray task failed: {type(exc).__name__}: "
                                                                 f"{str(exc).splitlines()[0] if str(exc) else ''}")
                if on_done is not None:
                    on_done(results[i])
        return [r for r in results if r is not None]
    finally:
        if started_here:
            ray.shutdown()
            if old_sigterm is not None:
                signal.signal(signal.SIGTERM, old_sigterm)

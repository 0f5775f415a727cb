"""A Dask scheduler and workers on 127.0.0.1 for the tests: ``dask scheduler`` and ``dask worker``
processes of this interpreter, bounded in time (idle and death timeouts, waits with deadlines) and
always stopped by the test."""
from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

START_TIMEOUT_S = 90.0


def _wait(pred, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = pred()
        if value:
            return value
        time.sleep(0.1)
    raise TimeoutError(f"{what} within {timeout:g} s")


def n_workers(address: str) -> int:
    from distributed import Client
    with Client(address, timeout=10, set_as_default=False) as c:
        return len(c.scheduler_info()["workers"])


@contextlib.contextmanager
def dask_cluster(tmp: Path, workers: int = 2):
    """Yield ``(address, [worker Popen, ...])``: a scheduler and ``workers`` single-threaded
    workers (no nanny, so that killing one kills the worker) on loopback."""
    tmp.mkdir(parents=True, exist_ok=True)
    sfile = tmp / "scheduler.json"
    logs = open(tmp / "dask.log", "w")
    procs = []
    py = [sys.executable, "-m", "dask"]
    try:
        procs.append(subprocess.Popen(py + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                            "--scheduler-file", str(sfile), "--idle-timeout", "600s"],
                                      stdout=logs, stderr=subprocess.STDOUT, cwd=tmp, start_new_session=True))
        address = _wait(lambda: sfile.exists() and json.loads(sfile.read_text() or "{}").get("address"),
                        START_TIMEOUT_S, "the dask scheduler did not start")
        wprocs = [subprocess.Popen(py + ["worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                                         "--host", "127.0.0.1", "--death-timeout", "60", "--name", f"w{k}",
                                         "--memory-limit", "0"],
                                   stdout=logs, stderr=subprocess.STDOUT, cwd=tmp, start_new_session=True)
                  for k in range(workers)]
        procs += wprocs
        _wait(lambda: n_workers(address) == workers, START_TIMEOUT_S, f"{workers} dask workers did not join")
        yield address, wprocs
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + 3
        for p in procs:
            try:
                p.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)
        logs.close()

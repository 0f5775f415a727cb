"""Execution back ends of batches: one small interface over a local process pool and Dask distributed.

A back end runs *tasks*: ``fn(*args)`` calls whose results are small (the
caller sends only seeds, specs and paths, and gets back error rows and
decimated series).  :meth:`Backend.run` takes an iterable of ``(key, fn, args)``
and yields ``(key, result_or_exception)`` as tasks finish, keeping at most
:attr:`Backend.window` tasks in flight, so that a million-task study never sits
whole in the client's (or the scheduler's) memory.

- :class:`InlineBackend` (``--jobs 1``): runs each task in this process when
  the iterator asks for it.
- :class:`PoolBackend` (``--jobs N``, the default): a ``ProcessPoolExecutor``
  of N spawned processes on this machine.
- :class:`DaskBackend` (``--scheduler tcp://HOST:PORT`` or ``local:N``): a
  ``distributed.Client`` on a running scheduler, or on a ``LocalCluster`` of N
  single-threaded worker processes started here.  Futures come back through
  ``distributed.as_completed(with_results=True, raise_errors=False)`` which is
  topped up as tasks finish.  A worker that dies is the scheduler's business:
  it reschedules the worker's tasks on the others (a task that has been on
  ``distributed.scheduler.allowed-failures`` + 1 dying workers, 4 by default,
  comes back as ``KilledWorker`` and is reported as that job's failure).  A
  task's own exception is deterministic (bad data, a numerical failure) and is
  returned as the job's error, never retried.

Signals: :func:`interrupt_signals` turns SIGINT, SIGTERM and SIGHUP into
:class:`Interrupted` in the client's main thread.  Worker processes started
here never see the terminal's SIGINT or SIGHUP (the signals are blocked while
they are spawned, and stay blocked in them): the client alone decides to stop
them, in :meth:`Backend.stop`, within a second.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import ctypes
import importlib.util
import itertools
import logging
import multiprocessing
import os
import signal
import socket
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from multiprocessing import resource_tracker

from .. import __version__
from ..errors import SinsError

log = logging.getLogger("sins")

TERMINAL_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_BLOCK_IN_WORKERS = {signal.SIGINT, signal.SIGHUP}
CONNECT_TIMEOUT_S = 10.0          # --scheduler tcp://...: give up connecting after this
WORKER_WAIT_S = 30.0              # ... and waiting for a first worker after this
INSTALL_HINT = "install the Dask extra: pip install 'sinscli[distributed]' (pip install '.[distributed]' in a checkout)"


class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP arrived while a batch ran (``signum`` says which)."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_status(self) -> int:
        return 128 + self.signum


class _SignalState:
    depth = 0                   # > 0 inside deferred_signals()
    pending: int | None = None


def _on_signal(signum, frame):
    if _SignalState.depth:
        _SignalState.pending = signum         # raised when the deferred section ends
        return
    raise Interrupted(signum)


@contextlib.contextmanager
def interrupt_signals():
    """Within the block, SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` in the main thread
    (at once, or at the end of a :func:`deferred_signals` section).

    Off the main thread (where Python cannot install handlers) the block runs unchanged.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _SignalState.pending = None
    old = {s: signal.signal(s, _on_signal) for s in TERMINAL_SIGNALS}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        _SignalState.pending = None


@contextlib.contextmanager
def deferred_signals():
    """A section that a signal must not cut in the middle (spawning workers, submitting to a library
    that holds locks meanwhile): the signal is raised as :class:`Interrupted` when it ends."""
    _SignalState.depth += 1
    try:
        yield
    finally:
        _SignalState.depth -= 1
    if _SignalState.depth == 0 and _SignalState.pending is not None:
        signum, _SignalState.pending = _SignalState.pending, None
        raise Interrupted(signum)


def hold_signals():
    """Ignore further SIGINT, SIGTERM and SIGHUP (while cleaning up after the first one); restored by
    :func:`interrupt_signals` on leaving its block."""
    if threading.current_thread() is threading.main_thread():
        for s in TERMINAL_SIGNALS:
            signal.signal(s, signal.SIG_IGN)


def _start_resource_tracker_quietly() -> None:
    """Start multiprocessing's resource tracker (once per process) with its stderr on /dev/null.  When a
    batch is interrupted, its workers are stopped without running their finalizers; the tracker then
    unlinks the semaphores they held, as it should, but warned about them ("leaked semaphore objects",
    "No such file or directory") on the user's terminal after sins's last line (the ``[SIGINT-group-pool]``
    case of tests/test_batch_interrupt.py, intermittently).  The clean-up stays; only its warnings go."""
    if getattr(resource_tracker._resource_tracker, "_fd", None) is not None:
        return
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)                      # the tracker inherits fd 2 when it is spawned
        resource_tracker.ensure_running()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


@contextlib.contextmanager
def _spawning():
    """Around code that starts worker processes or threads: SIGINT and SIGHUP are blocked in this
    thread, so the processes and threads started inside inherit the mask and pool and LocalCluster
    workers never receive the terminal's Ctrl-C or hang-up; any signal is deferred to the end."""
    with deferred_signals():
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        old = signal.pthread_sigmask(signal.SIG_BLOCK, _BLOCK_IN_WORKERS)
        try:
            with contextlib.suppress(OSError):
                _start_resource_tracker_quietly()
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


def ignore_terminal_signals() -> None:
    """In a worker process: ignore SIGINT and SIGHUP (the client stops its workers itself)."""
    for s in _BLOCK_IN_WORKERS:
        signal.signal(s, signal.SIG_IGN)


def pool_worker_init() -> None:
    """Initializer of the local pool's processes: ignore the terminal's signals, and die with the
    client even when it is killed (SIGKILL cannot be handled; Linux ``PR_SET_PDEATHSIG``)."""
    ignore_terminal_signals()
    with contextlib.suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)      # PR_SET_PDEATHSIG = 1


def dask_setup(worker=None) -> None:
    """Preload hook of the LocalCluster's workers (``preload=['sinscli.batch.exec']``)."""
    ignore_terminal_signals()


def where() -> str:
    """``host NAME`` of this process, with the Dask worker address when running on one."""
    host = socket.gethostname()
    try:
        from distributed import get_worker   # optional extra (sinscli[distributed]); not in a pool process
        return f"host {host} (Dask worker {get_worker().address})"
    except (ImportError, ValueError):
        return f"host {host}"


def worker_info() -> dict:
    """What the client checks on every Dask worker before sending jobs."""
    return {"host": socket.gethostname(), "sinscli": __version__, "pid": os.getpid()}


# --------------------------------------------------------------------------- back ends

def more_tasks(it: Iterator, room: int) -> list:
    """Up to ``room`` more tasks from ``it`` (none once it is exhausted)."""
    return list(itertools.islice(it, max(room, 0)))


class Backend:
    """Runs tasks; see the module docstring.  Use as a context manager (``stop`` on exit)."""

    description = ""
    capacity = 1                 # tasks that can run at once

    @property
    def window(self) -> int:
        """Tasks kept in flight: enough to keep every worker busy between round trips."""
        return 4 * self.capacity + 16

    def run(self, tasks: Iterable[tuple]) -> Iterator[tuple]:
        raise NotImplementedError

    def share(self, obj):
        """An argument that many tasks take: sent to the workers once where the back end can (Dask:
        scattered to every worker), else passed as it is."""
        return obj

    def stop(self, interrupted: bool = False) -> None:
        """Release the workers; with ``interrupted``, at once (running tasks are abandoned)."""

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.stop(interrupted=exc_type is not None)      # on any error or interrupt: at once
        return False


class InlineBackend(Backend):
    """``--jobs 1``: each task runs in this process when the iterator asks for its result."""

    description = "this process (--jobs 1)"

    def run(self, tasks):
        from ..io.atomic import immediate_outputs   # numpy: not for the back ends' workers and --help
        for key, fn, args in tasks:
            try:
                with immediate_outputs():        # a job's files are in place when it ends, as in a worker
                    out = fn(*args)
            except Exception as exc:  # noqa: BLE001 - the task's failure, reported by the caller
                out = exc
            yield key, out


class PoolBackend(Backend):
    """``--jobs N``: a ``ProcessPoolExecutor`` of N spawned processes."""

    def __init__(self, jobs: int):
        self.capacity = int(jobs)
        self.description = f"a local pool of {jobs} processes"
        with _spawning():                     # its queues start multiprocessing's resource tracker
            self._ex = cf.ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"),
                                              initializer=pool_worker_init)

    def run(self, tasks):
        it = iter(tasks)
        pending: dict = {}
        while True:
            for key, fn, args in more_tasks(it, self.window - len(pending)):
                with _spawning():                 # processes are spawned on submit
                    pending[self._ex.submit(fn, *args)] = key
            if not pending:
                return
            done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            for fut in done:
                key = pending.pop(fut)
                try:
                    out = fut.result()
                except cf.process.BrokenProcessPool as exc:
                    raise SinsError(f"a worker process of the local pool died ({exc}); the jobs finished so "
                                    "far are kept: rerun with --resume") from None
                except Exception as exc:  # noqa: BLE001
                    out = exc
                yield key, out

    def stop(self, interrupted=False):
        ex, self._ex = self._ex, None
        if ex is None:
            return
        if not interrupted:
            ex.shutdown(wait=True)
            return
        procs = list(getattr(ex, "_processes", {}).values())   # no public way to stop running tasks
        ex.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            with contextlib.suppress(Exception):
                p.kill()
        deadline = time.monotonic() + 1.0
        for p in procs:
            with contextlib.suppress(Exception):
                p.join(max(0.0, deadline - time.monotonic()))


def parse_scheduler(text: str) -> tuple[str, object]:
    """``local:N`` -> ("local", N); ``tcp://HOST:PORT`` (or another Dask comm URL) -> ("address", text)."""
    t = text.strip()
    if t.startswith("local:"):
        n = t[len("local:"):]
        if not n.isdigit() or int(n) < 1:
            raise SinsError(f"--scheduler {text}: expected local:N with N >= 1 worker processes")
        return "local", int(n)
    if "://" in t and t.split("://", 1)[1]:
        return "address", t
    raise SinsError(f"--scheduler {text}: expected tcp://HOST:PORT (a running Dask scheduler) or local:N")


def _import_distributed():
    try:
        import distributed   # optional extra (sinscli[distributed]), loaded only for --scheduler
    except ImportError:
        raise SinsError(f"--scheduler needs Dask distributed, which is not installed: {INSTALL_HINT}") from None
    return distributed


class DaskBackend(Backend):
    """``--scheduler``: a Dask ``Client`` on a running scheduler, or on a LocalCluster started here."""

    def __init__(self, scheduler: str, on_info: Callable[[str], None] | None = None, verbose: bool = False):
        kind, value = parse_scheduler(scheduler)
        distributed = _import_distributed()
        self._distributed = distributed
        self.cluster = None
        if not verbose:                         # worker-loss warnings etc.: only with -v / --debug
            for name in ("distributed", "distributed.nanny", "distributed.scheduler", "distributed.worker"):
                logging.getLogger(name).setLevel(logging.ERROR)
        try:
            if kind == "local":
                with _spawning(), warnings.catch_warnings():   # threads and workers inherit the mask
                    warnings.filterwarnings("ignore", message="Port .* is already in use")   # another port is taken
                    self.cluster = distributed.LocalCluster(
                        n_workers=value, threads_per_worker=1, processes=True, host="127.0.0.1",
                        dashboard_address="127.0.0.1:8787", silence_logs=logging.WARNING if verbose else logging.ERROR,
                        preload=["sinscli.batch.exec"])
                    self.client = distributed.Client(self.cluster, set_as_default=False)
                link = self.cluster.dashboard_link if self._has_dashboard() else "none (install bokeh)"
                self.description = (f"a Dask LocalCluster of {value} worker processes at "
                                    f"{self.cluster.scheduler_address}, dashboard {link}")
            else:
                with _spawning():
                    self.client = distributed.Client(value, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
                self.description = f"the Dask scheduler at {value}"
                link = self.client.dashboard_link if self._has_dashboard() else None
                if link:
                    self.description += f", dashboard {link}"
        except (OSError, TimeoutError) as exc:
            self._close_quietly()
            raise SinsError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler there "
                            f"within {CONNECT_TIMEOUT_S:g} s ({' '.join(str(exc).split())[:200]})") from None
        try:
            try:
                self.client.wait_for_workers(1, timeout=WORKER_WAIT_S)
            except (TimeoutError, OSError):
                raise SinsError(f"--scheduler {scheduler}: no Dask worker joined within {WORKER_WAIT_S:g} s") from None
            self._check_workers(scheduler)
            self.capacity = max(1, sum(self.client.nthreads().values()))
        except BaseException:
            self.stop(interrupted=True)
            raise
        if on_info:
            on_info(f"running on {self.description}")

    def _has_dashboard(self) -> bool:
        return importlib.util.find_spec("bokeh") is not None

    def _check_workers(self, scheduler):
        """Every worker must import the same sinscli (its functions are sent by reference)."""
        try:
            infos = self.client.run(worker_info)
        except Exception as exc:  # noqa: BLE001 - e.g. ModuleNotFoundError raised on a worker
            raise SinsError(f"--scheduler {scheduler}: a worker cannot run sins ({type(exc).__name__}: {exc}); "
                            "install the same sinscli on every worker") from None
        self._worker_pids = [info["pid"] for info in infos.values()]
        for addr, info in infos.items():
            if info["sinscli"] != __version__:
                raise SinsError(f"--scheduler {scheduler}: worker {addr} on host {info['host']} runs sinscli "
                                f"{info['sinscli']}, this client {__version__}: install the same version")

    def run(self, tasks):
        it = iter(tasks)
        token = f"{os.getpid():x}{time.time_ns() & 0xFFFFFFFF:x}"
        keys: dict = {}
        ac = self._distributed.as_completed(loop=self.client.loop, with_results=True, raise_errors=False)
        self._pending = keys

        def top_up():
            for key, fn, args in more_tasks(it, self.window - len(keys)):
                name = "-".join(str(k) for k in (key if isinstance(key, tuple) else (key,)))
                with deferred_signals():
                    fut = self.client.submit(fn, *args, key=f"sins-{name}-{token}", pure=False, retries=0)
                    keys[fut] = key
                    ac.add(fut)

        top_up()
        while keys:
            fut, out = next(ac)
            key = keys.pop(fut)
            if isinstance(out, BaseException) and not isinstance(out, Exception):
                out = RuntimeError(f"{type(out).__name__}: {out}")   # e.g. a CancelledError
            fut.release()
            yield key, out
            top_up()

    def share(self, obj):
        with deferred_signals():
            return self.client.scatter(obj, broadcast=True, hash=False)

    def _close_quietly(self):
        with contextlib.suppress(Exception):
            self.client.close(timeout=2)
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close(timeout=2)

    def stop(self, interrupted=False):
        client = getattr(self, "client", None)
        if client is None:
            return
        pending = list(getattr(self, "_pending", {}))
        self._pending = {}
        if interrupted and pending:
            with contextlib.suppress(Exception):
                client.cancel(pending, force=True)        # a running task is abandoned, its result dropped
        if interrupted and self.cluster is not None:
            # a worker busy in a task cannot answer a polite close: the nannies are told not to restart
            # their worker, and the worker processes are killed
            for nanny in list(getattr(self.cluster, "workers", {}).values()):
                with contextlib.suppress(Exception):
                    nanny.close_gracefully(reason="sins-interrupted")
            _kill_workers(getattr(self, "_worker_pids", []))
        with contextlib.suppress(Exception):
            client.close(timeout=1 if interrupted else 10)
        self.client = None
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close(timeout=1 if interrupted else 10)
            self.cluster = None


def _kill_workers(pids: list[int]) -> None:
    """Kill the LocalCluster's worker processes (children of this process) still alive after it closed."""
    try:
        import psutil   # comes with the optional distributed extra
    except ImportError:
        return
    mine = {p.pid: p for p in psutil.Process().children(recursive=True)}
    procs = [mine[pid] for pid in pids if pid in mine]
    for p in procs:
        with contextlib.suppress(Exception):
            p.kill()
    psutil.wait_procs(procs, timeout=0.5)


def open_backend(jobs: int | None = None, scheduler: str | None = None,
                 on_info: Callable[[str], None] | None = None, verbose: bool = False) -> Backend:
    """The back end of ``--jobs N`` / ``--scheduler S`` (raises :class:`SinsError` on a bad choice)."""
    if scheduler is not None:
        if jobs is not None:
            raise SinsError("--jobs and --scheduler: give one (--scheduler local:N runs N Dask workers here)")
        return DaskBackend(scheduler, on_info, verbose)
    jobs = max(1, int(jobs or os.cpu_count() or 1))
    return InlineBackend() if jobs == 1 else PoolBackend(jobs)

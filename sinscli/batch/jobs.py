"""Finished jobs on disk (``DIR/jobs/``), resuming, and what an interrupted batch leaves behind.

- :class:`JobStore`: each finished job's result is one ``.npz`` file (named
  arrays, plus a JSON ``meta`` string; no pickles) written atomically by the
  client as the result arrives.  ``jobs/fingerprint.json`` identifies the batch
  (its files and options): ``--resume`` refuses a ``jobs/`` folder written by
  another batch, and skips the jobs whose file exists.  A job that failed
  has no file, so ``--resume`` runs it again.
- :class:`OutputGuard`: what an interrupted run leaves is exactly the finished
  jobs' files under ``DIR/jobs/`` (and nothing at all if none finished):
  :meth:`OutputGuard.cleanup` removes every other file or folder the run
  created in ``DIR``, every temporary ``.part`` and every sidecar without its
  job file.
- :func:`run_tasks`: the loop over a :class:`~sinscli.batch.exec.Backend`'s
  results that writes each job file and reports failures.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..io.atomic import atomic_path, immediate_outputs
from .exec import Interrupted, hold_signals, interrupt_signals, open_backend

FINGERPRINT = "fingerprint.json"


def file_digest(path) -> str:
    """SHA-256 of a (small) file's bytes, for the fingerprint of a batch."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def file_stamp(path) -> list:
    """Size and modification time of a (large) input file, for the fingerprint of a batch (None for
    both when the client does not see it: the workers read it)."""
    try:
        st = os.stat(path)
    except OSError:
        return [str(path), None, None]
    return [str(path), st.st_size, st.st_mtime_ns]


class StudyInterrupted(Interrupted):
    """A batch stopped by a signal: ``finished`` of ``total`` jobs are kept in ``outdir/jobs``."""

    def __init__(self, signum: int, finished: int, total: int, outdir):
        super().__init__(signum)
        self.finished, self.total, self.outdir = finished, total, Path(outdir)

    def message(self) -> str:
        """The one line the command prints."""
        if self.finished == 0:
            return f"interrupted ({self.name}): no job had finished; nothing was written"
        if self.finished >= self.total:
            rest = "all jobs had finished but the report was not written: rerun with --resume to write it"
        else:
            rest = (f"rerun the same command with --resume to run the other {self.total - self.finished} "
                    "and write the report")
        return (f"interrupted ({self.name}): {self.finished} of {self.total} jobs had finished; their results "
                f"are kept in {self.outdir / 'jobs'}/ and nothing else was written; {rest}")


class JobStore:
    """``DIR/jobs/``: one ``<key parts>.npz`` per finished job."""

    def __init__(self, outdir, fingerprint: dict, resume: bool = False):
        self.dir = Path(outdir) / "jobs"
        self.fingerprint = json.loads(json.dumps(fingerprint))        # plain JSON types
        self.resume = resume
        self.replaced = 0

    def check(self) -> None:
        """Before anything is written: with ``resume``, the folder must belong to this batch."""
        if not self.resume:
            return
        fp = self.dir / FINGERPRINT
        if not fp.exists():
            raise SinsError(f"{self.dir}: --resume: no finished jobs of an earlier run here "
                            f"(no {FINGERPRINT}); run without --resume")
        try:
            old = json.loads(fp.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise SinsError(f"{fp}: --resume: cannot read it ({exc}); run without --resume") from None
        if old != self.fingerprint:
            what = sorted(k for k in set(old) | set(self.fingerprint) if old.get(k) != self.fingerprint.get(k))
            raise SinsError(f"{self.dir}: --resume: these jobs were run with other inputs or options "
                            f"(differing: {', '.join(what)}); run without --resume to start again")

    def open(self) -> None:
        """Create the folder (replacing an earlier run's unless resuming) with the fingerprint."""
        self.check()
        if not self.resume and self.dir.exists():
            self.replaced = sum(1 for _ in self.dir.rglob("*.npz"))
            shutil.rmtree(self.dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.dir / FINGERPRINT, now=True) as tmp:
            tmp.write_text(json.dumps(self.fingerprint, indent=1, sort_keys=True) + "\n", encoding="utf-8")

    def path(self, key: tuple) -> Path:
        return self.dir.joinpath(*(str(k) for k in key[:-1]), f"{key[-1]}.npz")

    def sidecar(self, key: tuple, suffix: str) -> Path:
        """A file a job writes beside its result (e.g. a trajectory ``.csv``), kept only with it."""
        p = self.path(key)
        return p.with_name(f"{p.stem}{suffix}")

    def done(self, key: tuple) -> bool:
        return self.path(key).exists()

    def write(self, key: tuple, meta: dict, arrays: dict[str, np.ndarray]) -> None:
        buf = io.BytesIO()
        np.savez(buf, meta=np.array(json.dumps(meta, sort_keys=True)), **arrays)
        with atomic_path(self.path(key), suffix=".part", now=True) as tmp:   # kept for --resume
            tmp.write_bytes(buf.getbuffer())

    def read(self, key: tuple) -> tuple[dict, dict[str, np.ndarray]]:
        path = self.path(key)
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except (OSError, ValueError, EOFError) as exc:
            raise SinsError(f"{path}: damaged job result ({exc}); remove it and run with --resume") from None
        return json.loads(str(arrays.pop("meta"))), arrays

    def count(self) -> int:
        return sum(1 for _ in self.dir.rglob("*.npz")) if self.dir.exists() else 0


def sweep_jobs(jobs: Path) -> None:
    """Remove from a ``jobs/`` folder all but the finished jobs' files and their sidecars: temporary
    ``.part`` files (of a run that was killed), sidecars without their job file, empty folders."""
    if not jobs.exists():
        return
    for root, dirs, files in os.walk(jobs, topdown=False):
        r = Path(root)
        for f in files:
            if f == FINGERPRINT and r == jobs:
                continue
            if not f.startswith(".") and (f.endswith(".npz") or (r / f"{f.split('.')[0]}.npz").exists()):
                continue                     # a finished job, or a sidecar of one (job stems have no dot)
            with contextlib.suppress(OSError):
                (r / f).unlink()
        for d in dirs:
            with contextlib.suppress(OSError):
                (r / d).rmdir()               # only if empty


def sweep_stale(outdir: Path) -> None:
    """What a killed run (SIGKILL cannot be handled) left in ``outdir``: staged reports and
    replaced folders (``.report.*.part``, ``.*.old.*``), and temporaries under ``jobs/``."""
    if not outdir.is_dir():
        return
    for p in outdir.iterdir():
        if p.name.startswith(".") and (p.name.endswith(".part") or ".old." in p.name):
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    p.unlink()
    sweep_jobs(outdir / "jobs")


class OutputGuard:
    """Remembers what ``outdir`` held before the run, to leave only finished jobs on an interrupt."""

    def __init__(self, outdir):
        self.outdir = Path(outdir)
        self.existed = self.outdir.exists()
        self.before = {p.name for p in self.outdir.iterdir()} if self.existed else set()

    def cleanup(self, store: JobStore) -> int:
        """Remove what the run created except finished jobs; returns how many finished jobs remain."""
        jobs = store.dir
        sweep_jobs(jobs)
        left = store.count()
        if left == 0 and jobs.exists() and "jobs" not in self.before:
            shutil.rmtree(jobs, ignore_errors=True)
        if self.outdir.exists():
            for p in self.outdir.iterdir():
                if p.name in self.before or (p.name == "jobs" and left):
                    continue
                if p.is_dir() and not p.is_symlink():
                    shutil.rmtree(p, ignore_errors=True)
                else:
                    with contextlib.suppress(OSError):
                        p.unlink()
            if not self.existed:
                with contextlib.suppress(OSError):
                    self.outdir.rmdir()               # only if empty
        return left


@dataclass
class TaskFailure:
    """A job that did not finish: its key and the error text (reported, never written to ``jobs/``)."""
    key: tuple
    meta: dict
    error: str


@dataclass
class RunCounts:
    total: int = 0
    resumed: int = 0
    ran: int = 0
    failures: list = field(default_factory=list)


def run_tasks(backend, store: JobStore, tasks: Iterable[tuple], describe: Callable[[BaseException], str],
              on_job: Callable[[tuple, dict], None] | None = None, counts: RunCounts | None = None) -> RunCounts:
    """Run ``tasks`` (``(task key, fn, args, job metas)``; ``fn`` returns a list of
    ``(job key, meta, arrays)``) on ``backend``; write each finished job to ``store``.

    A job whose meta has ``ok: False`` or whose task raised is recorded in ``counts.failures``.
    ``on_job(key, meta)`` is called for every job, finished or failed.
    """
    counts = counts or RunCounts()
    metas = {}

    def feed():
        for task_key, fn, args, job_metas in tasks:
            metas[task_key] = job_metas
            yield task_key, fn, args

    for task_key, out in backend.run(feed()):
        job_metas = metas.pop(task_key)
        if isinstance(out, BaseException):
            msg = describe(out)
            for key, meta in job_metas:
                counts.failures.append(TaskFailure(key, meta, msg))
                if on_job:
                    on_job(key, dict(meta, ok=False, error=msg))
            continue
        for key, meta, arrays in out:
            if meta.get("ok"):
                store.write(key, meta, arrays)
                counts.ran += 1
            else:
                counts.failures.append(TaskFailure(key, meta, meta.get("error", "")))
            if on_job:
                on_job(key, meta)
    return counts


def publish(stage: Path, outdir: Path) -> None:
    """Move a staged report into ``outdir``: files replace files, folders replace folders whole."""
    for p in sorted(stage.iterdir()):
        target = outdir / p.name
        if p.is_dir() and target.exists():
            old = outdir / f".{p.name}.old.{os.getpid()}"
            os.replace(target, old)
            os.replace(p, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            if target.is_dir():
                shutil.rmtree(target)
            os.replace(p, target)


def run_study(outdir, store: JobStore, keys: list[tuple], make_tasks: Callable[[object], Iterable[tuple]],
              finish: Callable[[Path, RunCounts], object], describe: Callable[[BaseException], str], *,
              jobs: int | None = None, scheduler: str | None = None, on_job=None, on_resumed=None,
              on_info=None, verbose: bool = False, backend: Callable[[], object] | None = None):
    """Run a study's jobs (``keys``) and write its report; the one loop of every batch command.

    ``make_tasks(backend)`` gives the tasks of the unfinished jobs (see :func:`run_tasks`; it may use
    ``backend.capacity`` and ``backend.share``);
    ``finish(stage, counts)`` writes the report into ``stage`` (a folder inside ``outdir``, moved into
    place when complete) and returns the result.  ``backend``: a factory of the back end, instead of
    the one of ``jobs`` / ``scheduler`` (:func:`~sinscli.batch.exec.open_backend`).  Any error or signal stops the workers at once and
    removes everything the run wrote but the finished jobs; a signal becomes :class:`StudyInterrupted`.
    Returns ``(result, counts)``.
    """
    outdir = Path(outdir)
    store.check()
    sweep_stale(outdir)
    guard = OutputGuard(outdir)
    counts = RunCounts(total=len(keys))
    with interrupt_signals():
        try:
            with (backend() if backend else open_backend(jobs, scheduler, on_info, verbose)) as runner:
                store.open()
                if store.replaced and on_info:
                    on_info(f"{store.dir}: replaced {store.replaced} job results of an earlier run "
                            "(--resume keeps them)")
                counts.resumed = sum(1 for k in keys if store.done(k))
                if on_resumed:
                    on_resumed(counts.resumed)
                run_tasks(runner, store, make_tasks(runner), describe, on_job, counts)
            stage = Path(tempfile.mkdtemp(prefix=".report.", suffix=".part", dir=outdir))
            with immediate_outputs():         # the report's files complete in the stage before publish moves them
                result = finish(stage, counts)
            publish(stage, outdir)
            stage.rmdir()
            return result, counts
        except BaseException as exc:
            hold_signals()
            left = guard.cleanup(store)
            if isinstance(exc, KeyboardInterrupt):
                raise StudyInterrupted(getattr(exc, "signum", 2), left, len(keys), outdir) from None
            raise

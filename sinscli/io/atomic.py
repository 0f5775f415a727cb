"""Output: every file is written through one staged mechanism, and every number through :func:`check_finite`.

A file is written under a temporary name beside its target (``.<name>.<pid>.part``, :func:`atomic_path`),
a folder set in a temporary folder beside its target folder (:func:`staged_dir`).  Nothing appears at a
target until the unit of work succeeds: each command is one :class:`OutputSet` (``sinscli/cli/base.py``),
whose staged files are flushed (fsync) and then renamed into place together, the earlier files kept
aside until every rename has succeeded.  So a failed, interrupted (SIGINT, SIGTERM, SIGHUP) or refused
run, or a disk that fills up, leaves nothing, or the previous complete set; a file system fault (disk
full, quota, I/O error, read-only) is one line naming the target, ``PATH: cannot write the output (No
space left on device)``.  A run killed with SIGKILL leaves its temporaries behind, and the next run that
writes the same target removes them (when that process is gone).  ``check_finite`` is the one guard
that no writer emits NaN or infinity (CSV, Parquet, MCAP, TUM, GeoJSON, KML, init YAML, report tables).
"""
from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import threading
from pathlib import Path

import numpy as np

from ..errors import SinsError, num
from ..inputs import command_inputs


def _same_file(a: str, b: str) -> bool:
    if a == b:
        return True
    try:
        return os.path.samefile(a, b)           # hard links, bind mounts
    except (OSError, ValueError):
        return False


def check_not_input(path) -> None:
    """Refuse an output ``path`` that is one of the command's inputs (the same file by its real path or
    by ``os.path.samefile``), or a file inside an input folder (a ROS 2 bag directory)."""
    inputs = command_inputs()
    if not inputs:
        return
    try:
        real = os.path.realpath(os.fspath(path))
    except (TypeError, ValueError, OSError):
        return
    for key, given in list(inputs.items()):
        inside = os.path.isdir(key) and real.startswith(key.rstrip(os.sep) + os.sep) and os.path.exists(real)
        if inside or _same_file(real, key):
            what = f"a file of the input {given}" if inside else f"the input {given}"
            raise SinsError(f"{target_of(Path(path))}: the output would overwrite {what}; "
                            f"give another output name")


class NonFiniteOutput(SinsError):
    """A writer was handed a NaN or infinity: an input slipped past the readers' checks."""


def check_finite(path, columns: dict, time=None, first_row: int = 1, sigmas=()) -> None:
    """Refuse to write ``columns`` (name -> array or number) if any value is NaN or infinite, or if a
    column named in ``sigmas`` (a 1-sigma) holds a value that is not positive.

    The message names the output (the target, when ``path`` is its temporary), the row (``first_row`` is
    the number of element 0, for a writer that streams in chunks), the epoch (``time``, when given) and
    the column of the first bad value.
    """
    sigmas = set(sigmas)
    for name, values in columns.items():
        a = np.asarray(values)
        if a.dtype.kind not in "fc":
            continue
        ok = np.isfinite(a)
        if name in sigmas:
            ok &= a > 0
        if ok.all():
            continue
        flat = ok.reshape(a.shape[0], -1).all(axis=1) if a.ndim else ok.reshape(1)
        k = int(np.argmax(~flat))
        value = a.reshape(a.shape[0], -1)[k][~ok.reshape(a.shape[0], -1)[k]][0] if a.ndim else a
        t = np.asarray(time) if time is not None else None
        where = f"{name!r}"
        if a.ndim:
            epoch = f" (time {num(t[k])} s)" if t is not None and t.ndim and k < t.shape[0] and np.isfinite(t[k]) \
                else ""
            where = f"row {first_row + k}{epoch}, column {where}"
        what = "a positive finite 1-sigma" if name in sigmas else "a finite number"
        raise NonFiniteOutput(f"{target_of(Path(path))}: internal consistency check: {where}: "
                              f"{num(value)} is not {what}; the input drives the computation outside its "
                              f"range; nothing written")


def output_lon_lat(path, lat_deg, lon_deg, time=None, first_row: int = 1):
    """The writers' guard of positions: ``(lat, lon)`` in degrees as every writer emits them, the longitude
    wrapped into [-180, 180) (RFC 7946, KML, docs/formats.md; across the antimeridian a navigator's longitude
    runs on past 180), after refusing a latitude outside [-90, 90] (a navigation that went over a pole,
    where the ENU mechanization does not hold) naming the output, row, epoch and column."""
    from ..nav.earth import wrap_lon
    lat = np.asarray(lat_deg, dtype=np.float64)
    bad = np.abs(lat) > 90.0
    if bad.any():
        k = int(np.argmax(bad.reshape(-1)))
        t = np.asarray(time).reshape(-1) if time is not None else None
        epoch = f" (time {num(t[k])} s)" if t is not None and k < t.shape[0] else ""
        raise NonFiniteOutput(f"{target_of(Path(path))}: internal consistency check: row {first_row + k}{epoch}, "
                              f"column 'lat': {num(lat.reshape(-1)[k])} deg is outside [-90, 90]: the navigation "
                              f"went over a pole, where the ENU frame is undefined (--frame launch-inertial holds "
                              f"there); nothing written")
    return lat_deg, wrap_lon(lon_deg, 180.0)


# temporary names shortened because the target's name is near the file system's limit (255 bytes):
# shortened name -> target name (for target_of)
_SHORT_NAMES: dict[str, str] = {}
NAME_MAX = 255


def target_of(path: Path) -> Path:
    """``path`` with every temporary name of this process in it (``.<name>.<pid>.part<suffix>``, a file
    of :func:`atomic_path` or a folder of :func:`staged_dir`) replaced by its target's name."""
    tag = f".{os.getpid()}.part"

    def one(p: str) -> str:
        if p in _SHORT_NAMES:
            return _SHORT_NAMES[p]
        base = p.split(".part", 1)[0] + ".part" if tag in p else p
        if base in _SHORT_NAMES:
            return _SHORT_NAMES[base]
        return p[1:p.index(tag)] if p.startswith(".") and tag in p else p
    parts = [one(p) for p in path.parts]
    return Path(*parts) if parts else path


def temp_sibling(path: Path, suffix: str = "") -> Path:
    """``<folder>/.<name>.<pid>.part<suffix>``: the temporary name of ``path`` for this process.  A target
    name near the 255-byte limit gets a shortened temporary name (its start and a hash), so that every
    name the file system allows can be written."""
    name = f".{path.name}.{os.getpid()}.part"
    if len(os.fsencode(name + suffix)) > NAME_MAX:
        import hashlib
        digest = hashlib.sha1(os.fsencode(path.name)).hexdigest()[:12]
        head = os.fsdecode(os.fsencode(path.name)[:120])
        name = f".{head}~{digest}.{os.getpid()}.part"
        _SHORT_NAMES[name] = path.name
    return path.parent / f"{name}{suffix}"


def _read_only(path: Path) -> str | None:
    """Why ``path`` (an existing file or folder) cannot be written, or None: a read-only file system, or a
    file without any write permission (replacing it, as a rename would, would defeat its protection)."""
    try:
        if os.statvfs(path).f_flag & os.ST_RDONLY:
            return "read-only file system"
    except (OSError, AttributeError):
        pass
    try:
        st = path.stat()
    except OSError:
        return None
    if not (st.st_mode & 0o222):           # not writable by anyone (root would write anyway)
        what = "folder" if path.is_dir() else "file"
        return f"the {what} is read-only: no write permission; remove it or give another name"
    return None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True
    return True


def remove_stale(path: Path) -> None:
    """Remove temporaries of ``path`` left by processes that are gone (a SIGKILL, a power cut)."""
    prefix = f".{path.name}."
    try:
        names = os.listdir(path.parent)
    except OSError:
        return
    for name in names:
        if not name.startswith(prefix) or ".part" not in name[len(prefix):]:
            continue
        pid = name[len(prefix):].split(".", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid() or _alive(int(pid)):
            continue
        p = path.parent / name
        if name.endswith(".part.old") and not os.path.lexists(path):
            with contextlib.suppress(OSError):        # killed while moving a set into place: the earlier file
                os.replace(p, path)
                continue
        _remove_tree(p)


def prepare_output(path, directory: bool = False, create: bool = False) -> Path:
    """Check an output path before anything is computed: not a directory (or, for ``directory``
    outputs, not a file), inside a folder that exists or can be made, writable.  Stale temporaries
    of it are removed; ``create`` makes its folder."""
    path = Path(path)
    for part in path.parts:
        if len(os.fsencode(part)) > NAME_MAX:
            raise SinsError(f"{path}: file name too long ({len(os.fsencode(part))} bytes; a name has at most "
                            f"{NAME_MAX})")
    check_not_input(path)
    if not directory and path.is_dir():
        raise SinsError(f"{path}: output is a directory; give a file name")
    if directory and path.exists() and not path.is_dir():
        raise SinsError(f"{path}: output is a file; give a folder name")
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise SinsError(f"{path}: {folder} is a file, not a folder")
    why = _read_only(folder)
    if why is not None:
        raise SinsError(f"{path}: cannot write in {folder}: {why}" if "no write" in why else
                        f"{path}: cannot write in {folder} ({why})")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise SinsError(f"{path}: cannot write in {folder} (permission denied)")
    if path.exists():
        why = _read_only(path)
        if why is not None:
            raise SinsError(f"{path}: cannot write the output: {why}")
    if create:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SinsError(f"{path}: cannot create the output folder {path.parent} "
                            f"({exc.strerror or type(exc).__name__})") from None
    remove_stale(path)
    return path


# Errors of the file system, not of the program: a full disk, a quota, a failing device, a read-only
# target, a folder removed under the run.  While an output is staged or moved into place they become
# ``TARGET: cannot write the output (<reason>)``, exit 2 (docs/contract.md, "Faults").
FAULT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO, errno.EROFS, errno.EACCES,
                          errno.EPERM, errno.EISDIR, errno.ENOTDIR, errno.ENAMETOOLONG, errno.ENOENT,
                          errno.EMLINK, errno.ETXTBSY, errno.EXDEV})
_ERRNO_TEXT = re.compile(r"\[errno (\d+)\]", re.I)     # pyarrow: "Error writing bytes ... [errno 28] ..."


def os_errno(exc: BaseException) -> int | None:
    """The errno of an ``OSError`` (also pyarrow's, which may carry it only in its text), else None."""
    if not isinstance(exc, OSError):
        return None
    if exc.errno:
        return int(exc.errno)
    m = _ERRNO_TEXT.search(str(exc))
    return int(m.group(1)) if m else None


def is_fault(exc: BaseException) -> bool:
    """True for an ``OSError`` of the file system (:data:`FAULT_ERRNOS`), not a bug."""
    return os_errno(exc) in FAULT_ERRNOS


def write_error(path, exc: BaseException) -> SinsError:
    """``TARGET: cannot write the output (No space left on device)``: the target, never its temporary."""
    code = os_errno(exc)
    why = os.strerror(code) if code else (getattr(exc, "strerror", None) or type(exc).__name__)
    return SinsError(f"{target_of(Path(path))}: cannot write the output ({why})")


def _fsync(path: Path) -> None:
    """Flush a staged file to the device, so that a full disk or a failing device is seen before the rename
    (a file system may report ENOSPC, EDQUOT or EIO only here)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _make_parents(path: Path) -> list[Path]:
    """Create the missing folders above ``path``; return them (outermost first) for :func:`_remove_empty`."""
    made = []
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        made.append(folder)
        folder = folder.parent
    for d in reversed(made):
        d.mkdir()
    return list(reversed(made))


def _remove_empty(folders) -> None:
    for d in reversed(list(folders)):
        with contextlib.suppress(OSError):
            d.rmdir()


class OutputSet:
    """The staged outputs of one unit of work: one command, or one folder set.  Nothing is at a target
    until :meth:`commit`, which checks every staged file (fsync) and moves them into place together; if
    any move fails, the earlier ones are undone, so a target holds the new complete set or the previous
    one.  :meth:`discard` removes the staged files and the folders made for them.
    """

    def __init__(self):
        self.moves: list[tuple[Path, Path]] = []      # (staged file, target)
        self.removals: list[Path] = []                # files of an earlier set this one does not have
        self.made: list[Path] = []                    # folders made for the staging
        self.cleanup: list[Path] = []                 # staging folders, removed at the end

    def add(self, staged: Path, target: Path) -> None:
        self.moves.append((Path(staged), Path(target)))

    def commit(self) -> None:
        for staged, target in self.moves:
            try:
                if not staged.is_dir():
                    _fsync(staged)
            except OSError as exc:
                self.discard()
                raise write_error(target, exc) from None
        try:
            for _, target in self.moves:
                check_not_input(target)
        except BaseException:
            self.discard()
            raise
        done = []            # [staged, target, backup of the earlier file, folders made, moved]
        current = None
        try:
            for staged, target in [*self.moves, *((None, t) for t in self.removals)]:
                current = target
                step = [staged, target, None, _make_parents(target), False]
                done.append(step)
                if os.path.lexists(target) and (staged is None or staged.is_dir() or not target.is_dir()):
                    step[2] = temp_sibling(target, ".old")
                    os.replace(target, step[2])
                if staged is not None:
                    os.replace(staged, target)
                    step[4] = True
        except BaseException as exc:
            for staged, target, backup, made, moved in reversed(done):   # undo: the previous set, complete
                with contextlib.suppress(OSError):
                    if moved:
                        os.replace(target, staged)
                with contextlib.suppress(OSError):
                    if backup is not None:
                        os.replace(backup, target)
                _remove_empty(made)
            self.discard()
            if is_fault(exc):
                raise write_error(current, exc) from None
            raise
        for step in done:
            if step[2] is not None:
                _remove_tree(step[2])
        self._finish()
        self.made = []

    def discard(self) -> None:
        for staged, _ in self.moves:
            _remove_tree(staged)
        self._finish()
        _remove_empty(self.made)
        self.made = []

    def _finish(self) -> None:
        for d in self.cleanup:
            _remove_tree(d)
        self.moves, self.removals, self.cleanup = [], [], []


def _remove_tree(p: Path) -> None:
    with contextlib.suppress(OSError):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink()


# The open output sets of this thread, innermost last.  A command (sinscli/cli/base.py) opens one, so
# that all its outputs appear together at its end or not at all; ``None`` marks the inside of a staging
# folder or of :func:`immediate_outputs`, whose files are moved into place at once.  Other threads (a
# batch's workers) have none: their files are moved at once.
_LOCAL = threading.local()


def _sets() -> list:
    if not hasattr(_LOCAL, "sets"):
        _LOCAL.sets = []
    return _LOCAL.sets


@contextlib.contextmanager
def output_set():
    """Stage every output written inside: moved into place together on success, none on failure."""
    s = OutputSet()
    _sets().append(s)
    try:
        yield s
    except SystemExit:              # the command's own exit status (a batch with failed jobs): its outputs stand
        _sets().remove(s)
        s.commit()
        raise
    except BaseException:
        _sets().remove(s)
        s.discard()
        raise
    _sets().remove(s)
    s.commit()


@contextlib.contextmanager
def immediate_outputs():
    """Inside, each output is moved into place when written (a batch job's results, read back by the
    same run and kept for ``--resume``), not at the end of the command."""
    _sets().append(None)
    try:
        yield
    finally:
        _sets().pop()


def commit_outputs() -> None:
    """Move the outputs the running command has staged so far into place now: before its last lines
    (``wrote ...``), so that a fault at the move is not reported after them."""
    s = _enclosing()
    if s is not None:
        s.commit()


def _enclosing() -> OutputSet | None:
    sets = _sets()
    return sets[-1] if sets else None


@contextlib.contextmanager
def _converted(target: Path):
    """OS faults while writing a staged output become the one-line write error naming ``target``."""
    try:
        yield
    except OSError as exc:
        if is_fault(exc):
            raise write_error(target, exc) from None
        raise


class StagedFile:
    """One output file written under a temporary name beside its target (:func:`temp_sibling`).

    :meth:`done` hands it to the enclosing :class:`OutputSet` (or moves it into place at once);
    :meth:`fail` removes it and returns the exception to raise (a file system fault as the write error).
    """

    def __init__(self, path, suffix: str | None = None, now: bool = False):
        self.path = prepare_output(path)
        self.made = []
        with _converted(self.path):
            self.made = _make_parents(self.path)
        self.tmp = temp_sibling(self.path, suffix or "")
        self._set = None if now else _enclosing()
        try:
            with contextlib.suppress(FileNotFoundError):
                self.tmp.unlink()                       # our own pid's leftover from an earlier, killed run
            fd = os.open(self.tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)  # the umask applies
            os.close(fd)
        except OSError as exc:
            _remove_empty(self.made)
            raise write_error(self.path, exc) from None

    def done(self) -> None:
        if self._set is not None:
            self._set.add(self.tmp, self.path)
            self._set.made.extend(self.made)
            return
        s = OutputSet()
        s.add(self.tmp, self.path)
        s.made = self.made
        s.commit()

    def fail(self, exc: BaseException | None = None) -> BaseException | None:
        _remove_tree(self.tmp)
        _remove_empty(self.made)
        if exc is not None and is_fault(exc):
            return write_error(self.path, exc)
        return exc


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None, now: bool = False):
    """Yield a temporary path in the target's folder; on success it becomes ``path``.

    Inside a command (an :func:`output_set`) the file is moved into place with the command's other
    outputs when the command succeeds; elsewhere, or with ``now`` (a batch's per-job results, kept for a
    resumed run), at once.  On any exception (or signal) the temporary file is removed and nothing is
    left at ``path`` (an existing file there is left untouched); a file system fault (disk full, quota,
    I/O error, read-only) becomes ``PATH: cannot write the output (<reason>)``.
    """
    f = StagedFile(path, suffix, now)
    try:
        yield f.tmp
    except BaseException as exc:
        err = f.fail(exc)
        if err is not exc:
            raise err from None
        raise
    try:
        f.done()
    except BaseException as exc:
        err = f.fail(exc)
        if err is not exc:
            raise err from None
        raise


@contextlib.contextmanager
def staged_dir(outdir, owned=(), replace: bool = False):
    """Yield a temporary folder beside ``outdir``; on success its files become the files of ``outdir``
    (created if needed), together with the enclosing command's other outputs.

    ``owned``: names (glob patterns) of the files of this kind of set; those of an earlier set that the
    new one lacks are removed with the move, so the folder never mixes two runs (``simulate``: imu.csv,
    gnss.csv, truth.csv, init.yaml).  ``replace``: the folder is one unit (a Parquet dataset), replaced
    whole.  Other files in ``outdir`` are left alone.  On failure nothing is left, and an earlier set is
    untouched.
    """
    outdir = prepare_output(outdir, directory=True)
    tmp = temp_sibling(outdir)
    _remove_tree(tmp)                                   # our own pid's leftover from an earlier, killed run
    made = []
    try:
        made = _make_parents(tmp)
        tmp.mkdir()
    except OSError as exc:
        _remove_empty(made)
        raise write_error(outdir, exc) from None
    try:
        with immediate_outputs(), _converted(outdir):
            yield tmp
    except BaseException:
        _remove_tree(tmp)
        _remove_empty(made)
        raise
    outer = _enclosing()
    s = outer if outer is not None else OutputSet()
    s.made.extend(made)
    if replace:
        s.add(tmp, outdir)
    else:
        produced = set()
        for p in sorted(tmp.rglob("*")):
            if not p.is_dir():
                rel = p.relative_to(tmp)
                produced.add(rel)
                s.add(p, outdir / rel)
        if outdir.is_dir():
            for pattern in owned:
                for old in sorted(outdir.glob(pattern)):
                    if old.is_file() and old.relative_to(outdir) not in produced:
                        s.removals.append(old)
        s.cleanup.append(tmp)
    if outer is None:
        s.commit()

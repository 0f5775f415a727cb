"""Output: every file is written through :func:`atomic_path` and every number through :func:`check_finite`.

``atomic_path`` writes to a temporary name beside the target and renames it on success, so a failed,
interrupted (SIGINT, SIGTERM, SIGHUP) or refused run leaves no file.  The temporary name is
``.<target name>.<pid>.part``: a run killed with SIGKILL leaves it behind, and the next run that writes
the same target removes it (when that process is gone).  ``check_finite`` is the one guard that no
writer emits NaN or infinity (CSV, Parquet, MCAP, TUM, GeoJSON, KML, init YAML, report tables).
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
from pathlib import Path

import numpy as np

from ..errors import SinsError, num
from ..inputs import command_inputs

_NO_SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS)


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


def target_of(path: Path) -> Path:
    """``path`` with every temporary name of this process in it (``.<name>.<pid>.part<suffix>``, a file
    of :func:`atomic_path` or a folder of :func:`staged_dir`) replaced by its target's name."""
    tag = f".{os.getpid()}.part"
    parts = [p[1:p.index(tag)] if p.startswith(".") and tag in p else p for p in path.parts]
    return Path(*parts) if parts else path


def temp_sibling(path: Path, suffix: str = "") -> Path:
    """``<folder>/.<name>.<pid>.part<suffix>``: the temporary name of ``path`` for this process."""
    return path.parent / f".{path.name}.{os.getpid()}.part{suffix}"


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
        with contextlib.suppress(OSError):
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                p.unlink()


def prepare_output(path, directory: bool = False, create: bool = False) -> Path:
    """Check an output path before anything is computed: not a directory (or, for ``directory``
    outputs, not a file), inside a folder that exists or can be made, writable.  Stale temporaries
    of it are removed; ``create`` makes its folder."""
    path = Path(path)
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
    if not os.access(folder, os.W_OK | os.X_OK):
        raise SinsError(f"{path}: cannot write in {folder} (permission denied)")
    if create:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SinsError(f"{path}: cannot create the output folder {path.parent} "
                            f"({exc.strerror or type(exc).__name__})") from None
    remove_stale(path)
    return path


def _write_error(path: Path, exc: OSError) -> SinsError:
    return SinsError(f"{path}: cannot write the output ({exc.strerror or type(exc).__name__})")


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path in the target's folder; rename it to ``path`` on success.

    On any exception (or signal) the temporary file is removed and nothing is left at
    ``path`` (an existing file there is left untouched).
    """
    path = prepare_output(path, create=True)
    tmp = temp_sibling(path, suffix or "")
    try:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()                            # our own pid's leftover from an earlier, killed run
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)   # the umask applies, as for any file
        os.close(fd)
    except OSError as exc:
        raise _write_error(path, exc) from None
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.errno in _NO_SPACE + (errno.EISDIR, errno.EACCES, errno.EPERM):
            raise _write_error(path, exc) from None
        raise


@contextlib.contextmanager
def staged_dir(outdir):
    """Yield a temporary directory beside ``outdir``; on success move its files into ``outdir`` (created
    if needed; files of an earlier run there are replaced one by one).  On failure nothing is left: the
    temporary directory is removed, and so is ``outdir`` when this call created it and it is empty."""
    outdir = prepare_output(outdir, directory=True)
    made = not outdir.exists()
    tmp = temp_sibling(outdir)
    shutil.rmtree(tmp, ignore_errors=True)          # our own pid's leftover from an earlier, killed run
    try:
        tmp.parent.mkdir(parents=True, exist_ok=True)
        tmp.mkdir()
    except OSError as exc:
        raise SinsError(f"{outdir}: cannot write the output ({exc.strerror or type(exc).__name__})") from None
    try:
        yield tmp
        for p in tmp.rglob("*"):                    # all checked before any is moved: all files or none
            if not p.is_dir():
                check_not_input(outdir / p.relative_to(tmp))
        outdir.mkdir(parents=True, exist_ok=True)
        for p in sorted(tmp.rglob("*")):
            rel = p.relative_to(tmp)
            if p.is_dir():
                (outdir / rel).mkdir(parents=True, exist_ok=True)
            else:
                (outdir / rel).parent.mkdir(parents=True, exist_ok=True)
                os.replace(p, outdir / rel)
    except BaseException:
        if made:
            with contextlib.suppress(OSError):
                outdir.rmdir()
        raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

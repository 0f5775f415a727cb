"""Where numba keeps the compiled kernels (``@njit(cache=True)``), decided before any kernel is defined.

Numba caches beside the source (``__pycache__``) or in the user's cache folder (``$XDG_CACHE_HOME`` or
``~/.cache``).  When neither is writable (an installed package run by a user whose HOME is read-only
or missing), every kernel definition would fail with "cannot cache function ...: no locator
available".  Then the cache goes to a private folder under the system's temporary directory, and
the CLI says so once.
"""
from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from pathlib import Path


def _writable(folder: Path) -> bool:
    """True when ``folder`` exists and is writable, or can be created (its nearest existing parent is)."""
    while not folder.exists():
        if folder.parent == folder:
            return False
        folder = folder.parent
    return folder.is_dir() and os.access(folder, os.W_OK | os.X_OK)


def _user_cache() -> Path | None:
    base = os.environ.get("XDG_CACHE_HOME")
    try:
        return Path(base) / "numba" if base else Path.home() / ".cache" / "numba"
    except RuntimeError:                       # no HOME and no passwd entry
        return None


def _private_temp_dir() -> Path:
    """``<tmp>/sins-numba-cache-<uid>``, owned by us and not writable by others; else a fresh one."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    d = Path(tempfile.gettempdir()) / f"sins-numba-cache-{uid}"
    try:
        d.mkdir(mode=0o700, exist_ok=True)
        st = d.lstat()
        if st.st_uid == uid and not (st.st_mode & 0o022) and d.is_dir() and os.access(d, os.W_OK | os.X_OK):
            return d
    except OSError:
        pass
    return Path(tempfile.mkdtemp(prefix="sins-numba-cache-"))


def ensure_cache_dir() -> str | None:
    """Point numba at a writable cache when it would find none; returns the note to show, or None."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given and _writable(Path(given)):
        return None
    if _writable(Path(__file__).resolve().parent / "nav" / "__pycache__"):
        return None
    user = _user_cache()
    if not given and user is not None and _writable(user):
        return None
    try:
        d = _private_temp_dir()
    except OSError:
        return None                            # nothing writable at all: numba's own error will say so
    os.environ["NUMBA_CACHE_DIR"] = str(d)
    if "numba" in sys.modules:                 # numba read its config already
        from numba.core import config   # numba is loaded already here; the package's import loads none
        config.CACHE_DIR = str(d)
    where = f"NUMBA_CACHE_DIR={given}" if given else f"{user or 'the home folder'}"
    return (f"cannot write numba's kernel cache (neither the package's __pycache__ nor {where} is writable); "
            f"compiled kernels are cached in {d}")


_announced = False          # a first-compile note was shown in this process
_note = None               # the running command's own text for it (set_compile_note), else the generic one


def set_compile_note(text: str) -> None:
    """The text of the first-compile note for the rest of the running command (``sins navigate`` names its
    kernels and the estimate of its first run) instead of the generic one of :func:`announce_compiles`."""
    global _note
    _note = text


@contextlib.contextmanager
def announce_compiles(echo, text: str):
    """While active (one command), the first numba compile of this process (a kernel missing from the
    on-disk cache) calls ``echo(note)`` once, before the compiler runs: the command says why it pauses.
    ``note`` is ``text``, or what the command gave :func:`set_compile_note`.

    Listens to numba's ``numba:compile`` event, which fires only when a kernel is compiled, never when
    it is loaded from the cache; once a note was shown, no later compile of the process repeats it.
    """
    global _note
    from numba.core import event   # numba only when a command compiles (sins --help loads none)

    class _FirstCompile(event.Listener):
        def on_start(self, ev):
            global _announced
            if not _announced:
                _announced = True
                echo(_note or text)

        def on_end(self, ev):
            pass

    _note = None
    try:
        with event.install_listener("numba:compile", _FirstCompile()):
            yield
    finally:
        _note = None

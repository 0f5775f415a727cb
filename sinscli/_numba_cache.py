"""Where numba keeps the compiled kernels (``@njit(cache=True)``), decided before any kernel is defined.

Numba caches beside the source (``__pycache__``) or in the user's cache folder (``$XDG_CACHE_HOME`` or
``~/.cache``).  When neither is writable (an installed package run by a user whose HOME is read-only
or missing), every kernel definition would fail with "cannot cache function ...: no locator
available".  Then the cache goes to a private folder under the system's temporary directory, and
the CLI says so once.
"""
from __future__ import annotations

import contextlib
import importlib.abc
import importlib.util
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


# --- a lean numba: no SciPy on the paths that need no linear algebra (issue 21) -------------------------
#
# Importing numba imports SciPy to check its version (``numba._ensure_critical_deps``, 15 ms), and the
# CPU target, initialised by the first kernel compiled *or loaded from the cache*, imports
# ``numba.np.arraymath``, whose start-up probe for BLAS (``_check_blas``) imports ``scipy.linalg``
# (0.2 s, with its Fortran libraries).  Neither is needed to run a kernel that calls no BLAS/LAPACK:
# numba's compiled linear algebra finds SciPy's routines through ``numba._helperlib`` at its first call,
# and numba checks SciPy again (``ensure_blas``/``ensure_lapack``, the ILP64 check) whenever it compiles
# one.  So when numba is imported after ``sinscli`` (every ``sins`` command), its import runs with
# ``scipy`` hidden, and ``arraymath``'s probe asks only whether SciPy is installed.  A command that needs
# SciPy imports it where it uses it; ``tests/test_cli_startup.py`` checks that plain navigation never does.

def _probe_blas() -> None:
    """``numba.np.arraymath``'s start-up probe: BLAS is there when SciPy is installed (not imported)."""
    if importlib.util.find_spec("scipy") is None:
        raise ImportError("scipy 0.16+ is required for linear algebra")


def _lean_arraymath() -> None:
    """Import ``numba.np.arraymath`` (the CPU target would, at its first kernel) with :func:`_probe_blas`
    as its BLAS probe; numba's own ``ensure_blas`` is put back for every later use."""
    if "numba.np.arraymath" in sys.modules:
        return
    import numba.np.linalg as nplinalg    # noqa: numba is imported here already
    real = nplinalg.ensure_blas
    nplinalg.ensure_blas = _probe_blas
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        nplinalg.ensure_blas = real


class _NumbaLoader(importlib.abc.Loader):
    """numba's own loader, run with ``scipy`` hidden (its version check is skipped: pyproject requires
    scipy >= 1.11), then :func:`_lean_arraymath`."""

    def __init__(self, loader):
        self._loader = loader

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        hide = "scipy" not in sys.modules
        if hide:
            sys.modules["scipy"] = None           # `import scipy` raises ImportError, which numba passes
        try:
            self._loader.exec_module(module)
        finally:
            if hide and "scipy" in sys.modules and sys.modules["scipy"] is None:
                del sys.modules["scipy"]
        _lean_arraymath()

    def __getattr__(self, name):                  # get_resource_reader, is_package, ... as numba's loader
        return getattr(self._loader, name)


class _NumbaFinder(importlib.abc.MetaPathFinder):
    """Finds ``numba`` once, through the other finders, and wraps its loader in :class:`_NumbaLoader`."""

    def find_spec(self, name, path=None, target=None):
        if name != "numba":
            return None
        with contextlib.suppress(ValueError):
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec("numba")
        if spec is not None and spec.loader is not None:
            spec.loader = _NumbaLoader(spec.loader)
        return spec


def lean_numba() -> None:
    """Make the coming import of numba lean (see above); when numba is loaded already, only the probe."""
    if "numba" in sys.modules:
        if "numba.np.arraymath" not in sys.modules and sys.modules["numba"] is not None:
            _lean_arraymath()
    elif not any(isinstance(f, _NumbaFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _NumbaFinder())

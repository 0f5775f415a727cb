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
import threading
import time
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
_note_seconds = None       # and its own estimate for the progress line (CompileProgress)


def set_compile_note(text: str, seconds: float | None = None) -> None:
    """The text of the first-compile note for the rest of the running command (``sins navigate`` names its
    kernels and the estimate of its first run) instead of the generic one of :func:`announce_compiles`;
    ``seconds``, the idle estimate of its compile, replaces the command's in the progress line."""
    global _note, _note_seconds
    _note, _note_seconds = text, seconds


class CompileProgress:
    """A refreshed line on ``stream`` while numba compiles (issue 21: never a silent minute): the seconds spent
    compiling so far against the estimate, redrawn every second on a terminal (``\\r``), a new line every
    ``every_s`` seconds elsewhere (logs, CI).  ``estimate_s`` is the idle machine's figure; the line scales it
    by the load (numba compiles on one thread: with L runnable jobs on N CPUs it gets about N/L of one)."""

    def __init__(self, stream, estimate_s: float | None, every_s: float = 15.0):
        self.stream = stream
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self.every_s = 1.0 if self.tty else every_s
        self.base_s = estimate_s
        self._lock = threading.Lock()
        self._io = threading.Lock()     # one writer of the line at a time (the refresher and the main thread)
        self._depth = 0                 # nested numba:compile events under way
        self._since = None              # perf_counter() when the outermost compile started
        self._spent = 0.0               # seconds of finished compiles
        self._drawn = False             # a terminal line is open (needs its newline)
        self._stop = threading.Event()
        self._thread = None

    def estimate(self) -> float | None:
        base = _note_seconds if _note_seconds is not None else self.base_s
        if base is None:
            return None
        try:
            load = os.getloadavg()[0]
        except OSError:
            load = 0.0
        return base * max(1.0, load / (os.cpu_count() or 1))

    def seconds(self) -> float:
        with self._lock:
            return self._spent + (time.perf_counter() - self._since if self._since is not None else 0.0)

    def line(self) -> str:
        t, est = self.seconds(), self.estimate()
        if est is None:
            return f"sins: kernels: {t:.0f} s so far (first run only)"
        if t <= est:
            return f"sins: kernels: {t:.0f} s of about {est:.0f} s (first run only)"
        return f"sins: kernels: {t:.0f} s, longer than the {est:.0f} s expected at this load (first run only)"

    def _draw(self, final: bool = False) -> None:
        text = self.line()
        with self._io:
            if final and not self._drawn:
                return
            if self.tty:
                self.stream.write("\r" + text + "\x1b[K" + ("\n" if final else ""))
                self._drawn = not final
            else:
                self.stream.write(text + "\n")
            self.stream.flush()

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            with self._lock:
                busy = self._depth > 0
            if busy:
                self._draw()

    def start(self) -> None:
        with self._lock:
            if self._depth == 0:
                self._since = time.perf_counter()
            self._depth += 1
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="sins-compile-progress", daemon=True)
            self._thread.start()

    def end(self) -> None:
        with self._lock:
            self._depth = max(0, self._depth - 1)
            if self._depth == 0 and self._since is not None:
                self._spent += time.perf_counter() - self._since
                self._since = None
            close = self._depth == 0 and self._drawn
        if close:
            self._draw(final=True)           # the terminal line ends where the compile ends

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._drawn:
            self._draw(final=True)


@contextlib.contextmanager
def announce_compiles(echo, text: str, progress: CompileProgress | None = None):
    """While active (one command), the first numba compile of this process (a kernel missing from the
    on-disk cache) calls ``echo(note)`` once, before the compiler runs: the command says why it pauses.
    ``note`` is ``text``, or what the command gave :func:`set_compile_note`.  With ``progress``, every
    compile of the command also drives that refreshed line (:class:`CompileProgress`).

    Listens to numba's ``numba:compile`` event, which fires only when a kernel is compiled, never when
    it is loaded from the cache; once a note was shown, no later compile of the process repeats it.
    """
    global _note, _note_seconds
    from numba.core import event   # numba only when a command compiles (sins --help loads none)

    class _FirstCompile(event.Listener):
        def on_start(self, ev):
            global _announced
            if not _announced:
                _announced = True
                echo(_note or text)
            if progress is not None:
                progress.start()

        def on_end(self, ev):
            if progress is not None:
                progress.end()

    _note = _note_seconds = None
    try:
        with event.install_listener("numba:compile", _FirstCompile()):
            yield
    finally:
        if progress is not None:
            progress.close()
        _note = _note_seconds = None


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

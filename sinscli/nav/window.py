"""Time windows of ``sins navigate --start/--end/--duration`` and ``sins compare --start/--end`` (issue 10).

Times are in the IMU log's clock (the values of its time column or message stamps); ``+S`` means S seconds
after the log's first epoch.  Navigation starts from the initial state, which must lie at or before the
window start (a trajectory file as ``--init`` gives its row at the start), runs over the IMU samples up to
the window end, and writes the rows from the window start on.  No I/O here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SinsError, num
from ..types import ImuLog, Trajectory, time_tolerance


@dataclass
class Window:
    """A time window; ``start``/``end`` are None for an open side; ``rel_*``: given as ``+S`` (relative to the
    first epoch of the log, resolved by :meth:`resolve`)."""
    start: float | None = None
    end: float | None = None
    duration: float | None = None
    rel_start: bool = False
    rel_end: bool = False

    @property
    def active(self) -> bool:
        return self.start is not None or self.end is not None or self.duration is not None

    def resolve(self, t_first: float) -> "Window":
        """Absolute start and end for a log whose first epoch is ``t_first``."""
        start = None if self.start is None else self.start + (t_first if self.rel_start else 0.0)
        end = None if self.end is None else self.end + (t_first if self.rel_end else 0.0)
        if self.duration is not None:
            end = (start if start is not None else t_first) + self.duration
        return Window(start, end)

    def text(self) -> str:
        a = "the start" if self.start is None else f"{num(self.start)} s"
        b = "the end" if self.end is None else f"{num(self.end)} s"
        return f"from {a} to {b}"


def parse_time(value: str | None, option: str) -> tuple[float | None, bool]:
    """``"123.5"`` -> (123.5, False); ``"+60"`` -> (60.0, True) (relative to the log's first epoch)."""
    if value is None:
        return None, False
    text = value.strip()
    rel = text.startswith("+")
    try:
        t = float(text)
    except ValueError:
        raise SinsError(f"{option}: expected a time in seconds (or +SECONDS after the log's first epoch), "
                        f"got {value!r}") from None
    if not np.isfinite(t) or abs(t) > 1e10:
        raise SinsError(f"{option}: expected a finite time within +-1e10 s, got {value!r}")
    return t, rel


def make_window(start: str | None, end: str | None, duration: float | None) -> Window:
    """The window of the ``--start``/``--end``/``--duration`` options (checked: end after start)."""
    if end is not None and duration is not None:
        raise SinsError("give --end or --duration, not both")
    if duration is not None and not (np.isfinite(duration) and 0 < duration <= 1e10):
        raise SinsError(f"--duration: expected a positive number of seconds, got {num(duration)}")
    s, rs = parse_time(start, "--start")
    e, re_ = parse_time(end, "--end")
    w = Window(s, e, duration, rs, re_)
    if s is not None and e is not None and rs == re_ and not e > s:
        raise SinsError(f"--end {end} is not after --start {start}")
    return w


def check_in_log(w: Window, t_first: float, t_last: float | None, source: str) -> None:
    """Refuse a window that ends before the log starts or starts after it ends (``t_last`` None: not known
    yet), or whose end is not after its start once resolved."""
    span = f"the log spans {num(t_first)} to {num(t_last)} s" if t_last is not None else \
        f"the log starts at {num(t_first)} s"
    if w.end is not None and w.end <= t_first + time_tolerance(t_first):
        raise SinsError(f"{source}: the window {w.text()} ends before the log starts ({span})")
    if w.start is not None and t_last is not None and w.start >= t_last - time_tolerance(t_last):
        raise SinsError(f"{source}: the window {w.text()} starts after the log ends ({span})")
    if w.start is not None and w.end is not None and not w.end > w.start:
        raise SinsError(f"{source}: the window {w.text()} is empty (its end is not after its start)")


def check_init(init_time: float, w: Window, init_src: str) -> None:
    """The initial state must lie at or before the window start."""
    if w.start is not None and init_time > w.start + time_tolerance(w.start):
        raise SinsError(f"{init_src}: the initial state is at {num(init_time)} s, after the window start "
                        f"{num(w.start)} s; give an init at or before the start (a trajectory file as --init "
                        f"gives its row at the start)")


def clip_imu(imu: ImuLog, end: float | None) -> ImuLog:
    """The samples whose interval ends at or before ``end``."""
    if end is None:
        return imu
    n = int(np.searchsorted(imu.time, end + time_tolerance(end), side="right"))
    return ImuLog(imu.time[:n], imu.dtheta_b[:n], imu.dvel_b[:n], t0=imu.t0, source=imu.source, kind=imu.kind,
                  resolution=imu.resolution)


def clip_blocks(blocks, end: float | None):
    """IMU blocks cut at ``end``: reading stops at the first block that reaches it."""
    for b in blocks:
        if end is None:
            yield b
            continue
        c = clip_imu(b, end)
        if len(c):
            yield c
        if len(c) < len(b):
            return


def trim(traj: Trajectory, w: Window) -> Trajectory:
    """The rows within the window (the start and end included within the time tolerance)."""
    keep = np.ones(len(traj), dtype=bool)
    if w.start is not None:
        keep &= traj.time >= w.start - time_tolerance(w.start)
    if w.end is not None:
        keep &= traj.time <= w.end + time_tolerance(w.end)
    if keep.all():
        return traj
    return Trajectory(traj.time[keep], traj.lat[keep], traj.lon[keep], traj.height[keep], traj.vel_n[keep],
                      traj.Cbn[keep], {k: np.asarray(v)[keep] for k, v in traj.extra.items()}, source=traj.source)


def windowed(chunks, w: Window, source: str):
    """Trajectory chunks trimmed to the window; SinsError at the end when none had a row in it (a window
    starting after the log ends), so that the writer leaves no file."""
    rows = 0
    for c in chunks:
        c = trim(c, w)
        if len(c):
            rows += len(c)
            yield c
    if rows == 0:
        raise SinsError(f"{source}: no navigation epoch in the window {w.text()}: it starts after the log ends")


def from_start(imu: ImuLog, start: float | None) -> ImuLog:
    """The samples after ``start`` (their first interval starts at the last epoch at or before it)."""
    if start is None:
        return imu
    k = int(np.searchsorted(imu.time, start + time_tolerance(start), side="right"))
    if k == 0:
        return imu
    return ImuLog(imu.time[k:], imu.dtheta_b[k:], imu.dvel_b[k:], t0=float(imu.time[k - 1]), source=imu.source,
                  kind=imu.kind, resolution=imu.resolution)


def cut_track(track, w: Window, source: str) -> None:
    """Cut a trajectory or a TUM track (any object of equal-length arrays with a ``time``) to the window,
    in place; SinsError when no row is left."""
    keep = np.ones(len(track), dtype=bool)
    if w.start is not None:
        keep &= track.time >= w.start - time_tolerance(w.start)
    if w.end is not None:
        keep &= track.time <= w.end + time_tolerance(w.end)
    if not keep.any():
        raise SinsError(f"{source}: no epoch in the window {w.text()} (the file spans {num(float(track.time[0]))} "
                        f"to {num(float(track.time[-1]))} s)")
    n = len(track)
    for name, value in list(vars(track).items()):
        if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == n:
            setattr(track, name, value[keep])
        elif isinstance(value, dict):
            setattr(track, name, {k: np.asarray(v)[keep] if np.ndim(v) and len(v) == n else v
                                  for k, v in value.items()})

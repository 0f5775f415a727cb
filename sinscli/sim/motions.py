"""Built-in analytic test motions with perfect sensors (no YAML needed).

Each returns a :class:`~sinscli.sim.run.SimResult` with error-free IMU
increments, perfect GNSS at 1 Hz and the exact truth.  Positions in degrees
and metres, durations in seconds, rates in Hz.
"""
from __future__ import annotations

from .run import SimResult, simulate


def _run(segments, start, rate, duration, name, gnss_rate=1.0) -> SimResult:
    sc = {"name": name, "start": start, "imu": {"rate": rate}, "gnss": {"rate": min(gnss_rate, rate)},
          "segments": segments, "duration": duration}
    return simulate(sc, perfect=True)


def _fill(pattern, duration, first=()):
    """``first`` then ``pattern`` repeated until the segments cover ``duration``."""
    segs, total = list(first), sum(s["duration"] for s in first)
    while total < duration:
        for s in pattern:
            segs.append(dict(s))
            total += s["duration"]
    return segs


def static(duration: float = 600.0, rate: float = 100.0, lat: float = 30.0, lon: float = 114.0,
           h: float = 50.0, heading: float = 0.0) -> SimResult:
    """At rest: ``w_ib^b = C_n^b w_ie^n``, ``f^b = -C_n^b g^n``, position constant."""
    return _run([{"type": "rest", "duration": duration}],
                {"lat": lat, "lon": lon, "height": h, "heading": heading}, rate, duration, "static")


DRIVE_PATTERN = [
    {"type": "accelerate", "speed": 15.0, "duration": 10.0},
    {"type": "cruise", "duration": 20.0},
    {"type": "turn", "angle": 90.0, "duration": 12.0, "bank": "none"},
    {"type": "climb", "pitch": 3.0, "duration": 30.0, "transition": 5.0},
    {"type": "accelerate", "speed": 20.0, "duration": 8.0},
    {"type": "turn", "angle": -120.0, "duration": 15.0, "bank": "none"},
    {"type": "cruise", "duration": 15.0},
    {"type": "descend", "pitch": 3.0, "duration": 30.0, "transition": 5.0},
    {"type": "turn", "angle": 45.0, "duration": 8.0, "bank": "none"},
    {"type": "decelerate", "speed": 8.0, "duration": 10.0},
    {"type": "turn", "angle": -90.0, "duration": 10.0, "bank": "none"},
    {"type": "accelerate", "speed": 18.0, "duration": 10.0},
    {"type": "turn", "angle": 75.0, "duration": 12.0, "bank": "none"},
    {"type": "decelerate", "speed": 0.0, "duration": 12.0},
    {"type": "rest", "duration": 8.0},
]


def drive(duration: float = 1200.0, rate: float = 100.0, lat: float = 30.0, lon: float = 114.0,
          h: float = 50.0) -> SimResult:
    """A land-vehicle drive: 10 s at rest, then turns, speed changes up to 20 m/s, climbs and descents."""
    segs = _fill(DRIVE_PATTERN, duration, first=[{"type": "rest", "duration": 10.0}])
    return _run(segs, {"lat": lat, "lon": lon, "height": h, "heading": 30.0}, rate, duration, "drive")


FULL_ATTITUDE_PATTERN = [
    {"type": "cruise", "duration": 5.0},
    {"type": "roll", "angle": 360.0, "duration": 10.0},                     # peak 79 deg/s
    {"type": "loop", "angle": 360.0, "duration": 20.0},
    {"type": "maneuver", "pitch": 360.0, "roll": 360.0, "duration": 20.0},  # barrel roll
    {"type": "pull_up", "angle": 90.0, "duration": 8.0},                    # to the vertical
    {"type": "roll", "angle": 180.0, "duration": 5.0},                      # roll while vertical
    {"type": "pitch", "angle": -180.0, "duration": 10.0},                   # over the top to -90
    {"type": "pitch", "angle": 90.0, "duration": 8.0},                      # recover to level
    {"type": "maneuver", "heading": 270.0, "pitch": 180.0, "roll": 360.0, "duration": 15.0},  # tumbling
    {"type": "roll", "angle": 1080.0, "duration": 30.0},                    # three rolls
    {"type": "turn", "angle": 180.0, "duration": 20.0},                     # coordinated, banked
    {"type": "maneuver", "pitch": 180.0, "duration": 10.0},                 # half loop, inverted
    {"type": "roll", "angle": 180.0, "duration": 5.0},                      # immelmann: upright
]


def full_attitude(duration: float = 600.0, rate: float = 100.0, lat: float = 30.0, lon: float = 114.0,
                  h: float = 3000.0) -> SimResult:
    """Aerobatics at 100 m/s: pitch through +-90 deg, repeated 360 deg rolls, loops, barrel rolls,
    tumbling; angular rates up to about 85 deg/s."""
    segs = _fill(FULL_ATTITUDE_PATTERN, duration)
    return _run(segs, {"lat": lat, "lon": lon, "height": h, "heading": 60.0, "speed": 100.0},
                rate, duration, "full_attitude")


def coning(duration: float = 60.0, rate: float = 100.0, half_angle_deg: float = 1.0, freq_hz: float = 1.0,
           lat: float = 30.0, lon: float = 114.0, h: float = 50.0) -> SimResult:
    """Pure coning at rest, from the first sample (no ramp).

    Analytic truth (FLU body, cone axis = body x, ``b`` = half angle,
    ``W = 2 pi freq``, ``t`` since start):

        Cbn(t) = C0 R(t),  R(t) = rotation by b about (0, cos Wt, sin Wt)
               = Rx(Wt) Ry(b) Rx(-Wt),   C0 = Rz(-0) Rx(0) Ry(0) C_FLU^RFU (level, north)
        q(t)   = [cos(b/2), 0, sin(b/2) cos Wt, sin(b/2) sin Wt]
        w_nb^b = (-2 W sin^2(b/2), -W sin b sin Wt, W sin b cos Wt)

    a rate vector of constant magnitude ``2 W sin(b/2)`` whose y-z part
    rotates at ``W``; ``w_ib^b = w_nb^b + C_n^b w_ie^n`` (at rest).
    """
    segs = [{"type": "coning", "half_angle": half_angle_deg, "freq": freq_hz, "duration": duration,
             "ramp": 0.0}]
    return _run(segs, {"lat": lat, "lon": lon, "height": h}, rate, duration, "coning")

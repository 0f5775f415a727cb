"""``sensor_msgs/Imu`` topics as increments, with the time rules of the CSV reader.

Header or log (receive) time; samples must be strictly increasing; gaps over 5
nominal intervals follow :class:`sinscli.io.imu_csv.TimeChecker`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import SinsError
from ...types import ImuLog, value_step
from .. import limits as limits_mod
from ..imu_csv import TimeChecker, rates_to_increments
from .containers import choose_topic, guard, open_log
from .decode import ACCEL, GYRO, IMU_TYPE, check_increasing, check_time_source, stamp_seconds

IMU_FIELDS = [f"{f}.{a}" for f in ("angular_velocity", "linear_acceleration") for a in "xyz"]


def read_imu_block(path, topic=None, bulk=True):
    """``(topic, log ns, ImuBlock)`` of an Imu topic (raw decode, no checks): used by tests and ``info``."""
    with open_log(path) as lg:
        topic = choose_topic(lg, topic, IMU_TYPE, "IMU", "--imu-topic")
        with guard(lg.path, topic, "cannot decode sensor_msgs/Imu messages"):
            t, block = lg.imu_block(topic, bulk=bulk)
    return topic, t, block


def read_imu(path, topic=None, time_source="header", start=None, end=None, bulk=True,
             allow_gaps=True, limits=None) -> ImuLog:
    """Read a ``sensor_msgs/Imu`` topic as increments (rates integrated by ``rates_to_increments``).

    Axes stay as in the message; the caller applies mounting and body convention.
    ``start``/``end`` (s, same time source) keep samples with ``start <= t <= end``.
    Gaps over 5 nominal intervals follow the CSV rule (:class:`sinscli.io.imu_csv.TimeChecker`):
    refused unless ``allow_gaps``, which bridges them with a warning naming each.
    Rates and specific forces beyond ``limits`` (the config's section; default: the defaults) are
    refused naming the message.  ``source`` is ``"file:topic"``.
    """
    check_time_source(time_source)
    path = Path(path)
    topic, log_ns, block = read_imu_block(path, topic, bulk=bulk)
    where = f"{path}: topic {topic}"
    if len(block) == 0:
        raise SinsError(f"{where}: topic has no messages")
    if time_source == "header":
        if np.any((block.nsec < 0) | (block.nsec >= 1_000_000_000)):
            k = int(np.flatnonzero((block.nsec < 0) | (block.nsec >= 1_000_000_000))[0])
            raise SinsError(f"{where}: header stamp of message {k} has nanoseconds {block.nsec[k]} (>= 1e9)")
        t = stamp_seconds(block.sec, block.nsec)
    else:
        t = stamp_seconds(log_ns // 1_000_000_000, log_ns % 1_000_000_000)
    gyro = block.values[:, GYRO]
    accel = block.values[:, ACCEL]
    keep = np.ones(t.shape[0], dtype=bool)
    if start is not None:
        keep &= t >= float(start)
    if end is not None:
        keep &= t <= float(end)
    if not keep.all():
        t, gyro, accel = t[keep], gyro[keep], accel[keep]
    if t.shape[0] == 0:
        raise SinsError(f"{where}: no messages between {start} and {end} s ({time_source} time; "
                        f"the topic spans {stamp_seconds(block.sec[:1], block.nsec[:1])[0]:.3f} .. "
                        f"{stamp_seconds(block.sec[-1:], block.nsec[-1:])[0]:.3f} s in header time)")
    if t.shape[0] < 2:
        raise SinsError(f"{where}: only one message in the requested interval; need at least two")
    check_increasing(t, where, f"{time_source} stamp")
    TimeChecker(where, allow_gaps, what=f"{time_source} stamp", row_label="message").check(t, 0)
    finite = np.isfinite(gyro).all(axis=1) & np.isfinite(accel).all(axis=1)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise SinsError(f"{where}: message {k} has a non-finite angular_velocity or linear_acceleration")
    limits_mod.check_imu_rates(where, gyro, accel, limits_mod.resolve(limits), IMU_FIELDS, 0, "message")
    time_end, dtheta, dvel, t0 = rates_to_increments(t, np.ascontiguousarray(gyro), np.ascontiguousarray(accel))
    return ImuLog(time=time_end, dtheta_b=dtheta, dvel_b=dvel, t0=t0, source=f"{path}:{topic}", kind="rates",
                  resolution=(value_step(gyro), value_step(accel)))

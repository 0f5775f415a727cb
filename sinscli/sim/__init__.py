"""Simulation with exact truth: scenarios -> IMU increments, GNSS fixes, truth trajectory.

``simulate(scenario, seed=None, perfect=False) -> SimResult`` and
``write_sim(result, outdir)``; built-in analytic motions in :mod:`.motions`.
"""
from .run import SimResult, simulate, write_sim  # noqa: F401
from . import motions  # noqa: F401,E402

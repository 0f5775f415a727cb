"""Command-line wiring: each command lives in its own module (listed in ``base.COMMANDS``),
registers itself on ``main`` and is imported when first used."""
import os

# One BLAS thread in a command (issue 21), set before numpy loads its OpenBLAS: its threads start on vectors
# of ~10,000 and more (a dot product of the GNSS time-offset search, nav/timesync.py) and spin waiting for
# work, 25x the CPU of one thread at load 15 (16 s of CPU in a fused run of 240,000 samples); the commands'
# parallel work is their own (numba kernels, the writer's threads, batch workers).  A user's setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from .base import main  # noqa: E402,F401

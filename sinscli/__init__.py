"""sins: strapdown inertial navigation of IMU/GNSS logs.

Layout: ``io`` (readers, writers) -> ``align`` / ``nav`` / ``report`` (pipeline
stages) -> ``io`` (writers); numerical kernels live in ``nav`` with no I/O.
"""
__version__ = "0.1.0"

from ._numba_cache import ensure_cache_dir as _ensure_cache_dir

#: set when numba's cache had to move to a temporary folder (the CLI prints it once as a warning)
NUMBA_CACHE_NOTE = _ensure_cache_dir()

"""sins: strapdown inertial navigation of IMU/GNSS logs.

Layout: ``io`` (readers, writers) -> ``align`` / ``nav`` / ``report`` (pipeline
stages) -> ``io`` (writers); numerical kernels live in ``nav`` with no I/O.
"""
__version__ = "0.1.0"

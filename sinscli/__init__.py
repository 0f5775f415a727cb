"""sins: strapdown inertial navigation of IMU/GNSS logs.

Layers, top to bottom (imports run down only; ``tests/test_layers.py`` checks it): ``cli`` -> ``batch``
-> ``report`` -> ``evaluate``, ``align`` -> ``allan``, ``sim`` -> ``fusion`` and ``io`` (siblings) -> ``gnss`` ->
``nav`` -> ``config``, ``sensors`` -> ``inputs``, ``frames`` -> ``errors``, ``types``, ``units``, ``layout``.
Numerical kernels live in ``nav`` (and ``fusion``, ``gnss``) with no I/O.
"""
__version__ = "0.1.0"

from ._numba_cache import ensure_cache_dir as _ensure_cache_dir, lean_numba as _lean_numba

_lean_numba()               # numba without SciPy where no kernel needs linear algebra (issue 21)

#: set when numba's cache had to move to a temporary folder (the CLI prints it once as a warning)
NUMBA_CACHE_NOTE = _ensure_cache_dir()

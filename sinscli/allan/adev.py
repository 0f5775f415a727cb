"""Overlapping Allan variance of IMU increments (IEEE Std 952-1997 annex C; Riley, NIST SP 1065 eq 14).

For increments ``d_k`` (angle or velocity over the sample interval ``tau0``)
the integrated signal ``x_k = sum_{i<k} d_i`` (``x_0 = 0``, N + 1 points) gives,
for a cluster of ``m`` samples (``tau = m tau0``),

    AVAR(tau) = sum_{k=0}^{N-2m} (x_{k+2m} - 2 x_{k+m} + x_k)^2 / (2 tau^2 (N + 1 - 2m))

in units of the rate squared (rad/s or m/s^2).  The mean increment is removed
first (second differences cancel it exactly; removing it keeps ``x`` small, so
that a gravity of 9.8 m/s^2 over hours does not cost digits).  One numba pass
over the samples per cluster size, all axes at once; no I/O.

The 1-sigma of a deviation is the usual approximation for ``K = N/m``
independent clusters (IEEE Std 952-1997 eq C.3; El-Sheimy et al. 2008):
``sigma(ADEV)/ADEV = 1 / sqrt(2 (K - 1))``.  For the overlapping estimator it
is conservative: for white noise the spread is about 0.82 of it
(``tests/test_allan.py`` measures it).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange


def cluster_sizes(n: int, per_decade: int = 10, min_clusters: int = 4) -> np.ndarray:
    """Log-spaced cluster sizes ``m`` (samples) from 1 to ``n // min_clusters``, unique integers."""
    m_max = max(n // min_clusters, 1)
    k = np.arange(0, int(np.floor(np.log10(m_max) * per_decade)) + 1)
    return np.unique(np.round(10.0 ** (k / per_decade)).astype(np.int64))


@njit(cache=True)
def integrate_into(x, col0, inc, mean):
    """``x[:, col0:col0 + K]``: ``x_0 = 0``, ``x_{k+1} = x_k + (inc_k - mean)`` for increments (N, K)."""
    n, kdim = inc.shape
    for c in range(kdim):
        x[0, col0 + c] = 0.0
    for k in range(n):
        for c in range(kdim):
            x[k + 1, col0 + c] = x[k, col0 + c] + (inc[k, c] - mean[c])


NCHUNK = 16             # the sum over k in chunks: the order of the additions, hence the last bits


@njit(cache=True)
def _chunk_sums(x, m, ch, part):
    """``part[ch]``: chunk ``ch`` of :data:`NCHUNK` of ``sum_k (x_{k+2m} - 2 x_{k+m} + x_k)^2``, per column."""
    n1, kdim = x.shape
    total = n1 - 2 * m
    k0 = total * ch // NCHUNK
    k1 = total * (ch + 1) // NCHUNK
    for c in range(kdim):
        part[ch, c] = 0.0
    for k in range(k0, k1):
        for c in range(kdim):
            d = x[k + 2 * m, c] - 2.0 * x[k + m, c] + x[k, c]
            part[ch, c] += d * d


@njit(cache=True)
def _add_chunks(part, out, a):
    """``out[a, c] = sum over chunks of part[:, c]``, in chunk order (a loop, not ``np.sum``: under
    ``parallel=True`` numba would split that sum over its threads, and the bits would follow the threads)."""
    for c in range(part.shape[1]):
        acc = 0.0
        for ch in range(part.shape[0]):
            acc += part[ch, c]
        out[a, c] = acc


@njit(cache=True, parallel=True)
def second_difference_sums(x, ms):
    """``sum_k (x_{k+2m} - 2 x_{k+m} + x_k)^2`` for each ``m`` in ``ms`` and each column: (len(ms), K).

    The sum over k is split into :data:`NCHUNK` chunks summed on the available cores (the order of the
    additions, hence the last bits, depends on the chunking only, not on the thread count).
    """
    out = np.zeros((ms.shape[0], x.shape[1]))
    part = np.zeros((NCHUNK, x.shape[1]))
    for a in range(ms.shape[0]):
        for ch in prange(NCHUNK):
            _chunk_sums(x, ms[a], ch, part)
        _add_chunks(part, out, a)
    return out


@njit(cache=True)
def _all_chunks(x, m, part):
    """Every chunk of :func:`_chunk_sums`, in order, on this thread."""
    for ch in range(NCHUNK):
        _chunk_sums(x, m, ch, part)


@njit(cache=True)
def second_difference_sums_serial(x, ms):
    """:func:`second_difference_sums` on one thread, the same chunks in the same order (the same bits): for
    short stretches (the fusion's and the alignment's rest windows), where starting numba's thread pool and
    its waits cost more CPU than the sums (issue 21: 1.2 s of CPU in a fused run of 240,000 samples)."""
    out = np.zeros((ms.shape[0], x.shape[1]))
    part = np.zeros((NCHUNK, x.shape[1]))
    for a in range(ms.shape[0]):
        _all_chunks(x, ms[a], part)
        _add_chunks(part, out, a)
    return out


PARALLEL_MIN_ROWS = 1 << 20     # samples from which the sums go to numba's threads


def overlapping_avar(inc, tau0: float, ms: np.ndarray, progress=None) -> np.ndarray:
    """Overlapping Allan variance (len(ms), K) of increments ``inc`` (N, K) sampled every ``tau0`` s,
    or of several such arrays side by side (a tuple: their columns in order).

    ``progress(k)`` is called after each cluster size (``k`` = 1).
    """
    parts = [np.ascontiguousarray(p, dtype=np.float64) for p in (inc if isinstance(inc, tuple) else (inc,))]
    n = parts[0].shape[0]
    x = np.empty((n + 1, sum(p.shape[1] for p in parts)))
    col = 0
    for p in parts:
        integrate_into(x, col, p, p.mean(axis=0))
        col += p.shape[1]
    out = np.empty((ms.shape[0], x.shape[1]))
    sums = second_difference_sums if n >= PARALLEL_MIN_ROWS else second_difference_sums_serial
    for a in range(ms.shape[0]):
        out[a] = sums(x, ms[a:a + 1])[0]
        if progress is not None:
            progress(1)
    m = ms.astype(np.float64)
    return out / (2.0 * (m * tau0) ** 2 * (n + 1 - 2 * m))[:, None]


def adev_relative_sigma(n: int, ms: np.ndarray) -> np.ndarray:
    """``1 / sqrt(2 (n/m - 1))``: the relative 1-sigma of each deviation (see the module docstring)."""
    return 1.0 / np.sqrt(2.0 * (n / ms.astype(np.float64) - 1.0))

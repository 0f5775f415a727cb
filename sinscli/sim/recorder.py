"""What the logger does to the samples: the written values' quantization and dropped rows.

**Quantization of the output** (Groves 2013, "Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems", 2nd ed., sec. 4.4: quantization residuals of a digital output).  Rate samples
(``imu.output: rates``) are each rounded to the step, ``x_q = round(x / q) q``, as a chip's register or a
logger's fixed decimals do (1 mg: three decimals in g); the rounding error is not carried, so a still
sensor without vibration reads a constant, biased by up to ``q/2``, and vibration of more than a step
dithers it into white noise of variance ``q^2/12``.  Increments are a counter's: the step is ``q dt`` (the
rate step times the nominal interval) and the remainder is carried to the next sample
(:func:`sinscli.sim.errors.quantize`), so the quantization noise is white in the increments and their
sum is off by less than one step at any time.

**Dropped samples**: runs of consecutive rows removed (a logger's lost packets), their lengths uniform
in ``[run_min, run_max]``, their number ``round(fraction * N / mean run)``, placed at random with at
least one kept row between runs; the first and the last instant are always kept.  The kept rows are
unchanged (their stamps and values are those of the run without drops).
"""
from __future__ import annotations

import numpy as np

from ..errors import SinsError


def round_to_step(x: np.ndarray, step: float) -> np.ndarray:
    """``round(x / step) step`` (step > 0), else ``x``."""
    if step <= 0.0:
        return x
    return np.round(x / step) * step


def dropped_instants(n_instants: int, fraction: float, run: tuple[int, int], rng: np.random.Generator,
                     where: str = "imu.dropped") -> np.ndarray:
    """Indices (sorted) of the instants ``1..n_instants-2`` to drop (module docstring); empty for
    ``fraction`` 0."""
    lo, hi = run
    inner = n_instants - 2
    n_runs = int(round(fraction * inner / (0.5 * (lo + hi))))
    if n_runs == 0 or inner <= 0:
        return np.zeros(0, dtype=np.int64)
    lengths = rng.integers(lo, hi + 1, size=n_runs)
    kept = inner - int(lengths.sum())
    if kept < n_runs + 1:
        raise SinsError(f"{where}: fraction {fraction:g} with runs of {lo}-{hi} leaves no kept sample between "
                        f"the runs ({n_runs} runs in {inner} samples); use a smaller fraction")
    # kept rows in n_runs + 1 non-empty blocks: n_runs distinct cuts among the kept - 1 inner positions
    cuts = np.sort(rng.choice(kept - 1, size=n_runs, replace=False)) + 1
    blocks = np.diff(np.concatenate([[0], cuts, [kept]]))
    out = []
    pos = 1                                    # instant 0 always kept
    for b, length in zip(blocks[:-1], lengths):
        pos += int(b)
        out.append(np.arange(pos, pos + int(length)))
        pos += int(length)
    return np.concatenate(out).astype(np.int64)


def runs_of(indices: np.ndarray) -> np.ndarray:
    """Lengths of the runs of consecutive indices (sorted ``indices``)."""
    if indices.size == 0:
        return np.zeros(0, dtype=np.int64)
    breaks = np.nonzero(np.diff(indices) != 1)[0]
    ends = np.concatenate([breaks, [indices.size - 1]])
    starts = np.concatenate([[0], breaks + 1])
    return (ends - starts + 1).astype(np.int64)

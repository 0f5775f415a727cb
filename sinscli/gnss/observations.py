"""The observation table that the RINEX and UBX readers fill: epochs, satellite records, one column per
observation code of the record's system (plain arrays; no per-record Python objects)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .signals import SYS_CHARS, sat_name


@dataclass
class ObsData:
    """Observations of one receiver.

    ``time[e]`` (GPS seconds, receiver clock time) is epoch e; its satellite records are rows
    ``start[e]:start[e+1]`` of ``sys``, ``prn``, ``values``, ``lli``.  ``types[s]`` lists the RINEX 3 codes
    of system s in column order: ``values[r, j]`` is code ``types[sys[r]][j]`` (m, cycles, Hz, dB-Hz), NaN when
    absent.  ``line[r]`` is the file line of record r (0 when not from a text file), for messages.
    """
    time: np.ndarray                 # (E,) float64 GPS seconds
    start: np.ndarray                # (E+1,) int64
    sys: np.ndarray                  # (R,) int8
    prn: np.ndarray                  # (R,) int16
    values: np.ndarray               # (R, K) float64
    lli: np.ndarray                  # (R, K) int8 (loss-of-lock indicator; 0 when blank)
    types: dict                      # sys -> list of codes
    flag: np.ndarray | None = None   # (E,) epoch flags
    line: np.ndarray | None = None   # (R,) int64 file line of each record
    epoch_line: np.ndarray | None = None
    header: dict = field(default_factory=dict)   # version, marker, approx_xyz, receiver, antenna, interval, ...
    source: str = "<memory>"
    glo_freq: dict = field(default_factory=dict)  # GLONASS slot -> frequency channel k
    ssi: np.ndarray | None = None    # (R, K) int8 signal strength indicator (RINEX 1-9; 0 when blank)

    def __len__(self) -> int:
        return int(self.time.shape[0])

    @property
    def n_records(self) -> int:
        return int(self.sys.shape[0])

    def epoch_of_record(self) -> np.ndarray:
        """(R,) epoch index of each record."""
        return np.repeat(np.arange(len(self)), np.diff(self.start))

    def column(self, code_options, sys: int) -> tuple[np.ndarray, np.ndarray]:
        """``(values, code_index)`` per record of system ``sys``: for each record the first of ``code_options``
        present (not NaN); NaN where none is.  ``code_index`` says which option (-1 none)."""
        n = self.n_records
        out = np.full(n, np.nan)
        which = np.full(n, -1, dtype=np.int8)
        mine = self.sys == sys
        types = self.types.get(sys, [])
        for i, code in enumerate(code_options):
            if code not in types:
                continue
            v = self.values[:, types.index(code)]
            take = mine & np.isnan(out) & ~np.isnan(v)
            out[take] = v[take]
            which[take] = i
        return out, which

    def satellites(self) -> list[str]:
        """Names (``G05``) of the satellites observed."""
        ids = np.unique(self.sys.astype(np.int64) * 1000 + self.prn)
        return [sat_name(int(i // 1000), int(i % 1000)) for i in ids]

    def system_letters(self) -> str:
        return "".join(SYS_CHARS[s] for s in sorted({int(s) for s in np.unique(self.sys)}))

"""The reference a healthy machine matches, learned from its first cycles.

The activation model (D1) books each stroke's air from the drive's geometry; a real
machine's drives, tubes and meter take a few per cent more or less, the same every cycle
(on the served pick-and-place about 7 % less). Judged against D1 alone, that constant
part of the gap hides a fault of the same size. The learned reference keeps D1's
account of *what* the machine did (each consumer's air from the cycle's valve edges) and
learns *how much* each consumer's air really is: one scale factor per consumer, fitted by
least squares over the first ``cycles`` cycles, held towards their common ratio (the
median of measured over predicted) where the learning cycles do not tell the consumers
apart (a machine that repeats one cycle gives the ratio for all). A cycle's expected air
is then the sum of its consumers' D1 air times their factors; a departure from it is a
change since the learning cycles.

Pure arithmetic on what it is fed: no I/O."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# how strongly the per-consumer factors are held towards the common ratio, relative to
# the learning cycles' own weight: enough to fix what the cycles leave open, too little
# to override what they show
RIDGE = 1e-3
SCALE_RANGE = (0.25, 4.0)     # a factor beyond this is a wrong machine file, not a drive


@dataclass
class LearnedReference:
    """Per-consumer scale factors on D1, learned from the first ``cycles`` cycles
    compared (0: none, the reference is D1 itself)."""
    names: list
    cycles: int
    rows: list = field(default_factory=list)       # (cycle number, D1 NL per consumer, measured)
    scale: np.ndarray | None = None
    ratio: float | None = None
    first: int | None = None
    last: int | None = None
    fit_rms_percent: float | None = None

    @property
    def learned(self) -> bool:
        return self.scale is not None

    @property
    def learning(self) -> bool:
        return self.cycles > 0 and self.scale is None

    def label(self) -> str:
        """How the terminal and the events name the reference."""
        if self.cycles <= 0:
            return "D1"
        if self.scale is None:
            return f"learning {len(self.rows)}/{self.cycles}"
        return f"learned from cycles {self.first}-{self.last}"

    def add(self, number: int, by_consumer: np.ndarray, measured_nl: float) -> bool:
        """Take a cycle while learning; whether the reference has just been learned."""
        if not self.learning or not float(np.sum(by_consumer)) > 0:
            return False
        self.rows.append((number, np.asarray(by_consumer, float), float(measured_nl)))
        if len(self.rows) < self.cycles:
            return False
        self._fit()
        return True

    def _fit(self) -> None:
        A = np.array([r[1] for r in self.rows])
        m = np.array([r[2] for r in self.rows])
        self.ratio = float(np.median(m / A.sum(axis=1)))
        # s = ratio + d, minimising |A d - (m - ratio A 1)|^2 + lam |d|^2
        residual = m - self.ratio * A.sum(axis=1)
        lam = RIDGE * float(np.trace(A.T @ A))
        d = np.linalg.solve(A.T @ A + lam * np.eye(A.shape[1]), A.T @ residual)
        self.scale = np.clip(self.ratio + d, SCALE_RANGE[0] * self.ratio,
                             SCALE_RANGE[1] * self.ratio)
        fitted = A @ self.scale
        self.fit_rms_percent = float(100.0 * np.sqrt(np.mean(((m - fitted) / fitted) ** 2)))
        self.first, self.last = self.rows[0][0], self.rows[-1][0]
        self.rows = []

    def expected_nl(self, by_consumer: np.ndarray) -> float | None:
        """A cycle's expected air (NL): D1 where nothing is learned to be, None while
        learning."""
        if self.cycles <= 0:
            return float(np.sum(by_consumer))
        if self.scale is None:
            return None
        return float(np.dot(self.scale, by_consumer))

    def summary(self) -> dict:
        return {"reference": self.label(), "from_cycle": self.first, "to_cycle": self.last,
                "ratio": self.ratio, "fit_rms_percent": self.fit_rms_percent,
                "scale": None if self.scale is None else
                {n: float(s) for n, s in zip(self.names, self.scale)}}

"""The paper's reference numbers that results are compared with (Leitner et al., section 4):
Table 7 (RecurDyn re-runs of KP/BW with the calibrated Table 6 parameters), the real-world
tests the calibration aimed at, and RecurDyn's wall times.

Table 7 and the real-world tests belong to the KP/BW consignment; reports show them for
another consignment as orientation only (no ratio).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "REFERENCE_CONSIGNMENT",
    "Reference",
    "TEST_REFERENCES",
    "RECURDYN_WALL_S",
    "PAPER_SIMULATED_S",
    "RECURDYN_CONVEYOR_WALL_S",
    "RECURDYN_CONVEYOR_SIMULATED_S",
    "recurdyn_wall_s",
]

REFERENCE_CONSIGNMENT = "KPBW"
"""The consignment of Table 7 and of the real-world tests."""


@dataclass(frozen=True)
class Reference:
    """One response of Table 7: ``label``, ``test`` (scenario name), ``response`` (its key),
    ``table7`` (RecurDyn) and ``real`` (the real-world test) [mm]."""

    label: str
    test: str
    response: str
    table7: float
    real: float


TEST_REFERENCES: tuple[Reference, ...] = (
    Reference("first swing", "swing", "first_swing_mm", 128.0, 127.0),
    Reference("second swing", "swing", "second_swing_mm", 27.0, 32.0),
    Reference("vertical drop rebound", "drop-vertical", "rebound_mm", 6.2, 7.0),
    Reference("horizontal drop rebound", "drop-horizontal", "rebound_mm", 4.5, 4.0),
)
"""Paper Table 7 [mm] and the real-world tests [mm] (paper Fig. 27 and section 4.3)."""

RECURDYN_WALL_S = {"swing": 384.0, "drop-vertical": 125.0, "drop-horizontal": 76.0}
"""RecurDyn wall times of Table 7 [s] (Intel i9-13900H, 4 cores) for the paper's simulated
times :data:`PAPER_SIMULATED_S`."""
PAPER_SIMULATED_S = {"swing": 1.4, "drop-vertical": 0.3, "drop-horizontal": 0.3}
"""Simulated time of each of the paper's tests [s]."""
RECURDYN_CONVEYOR_WALL_S = 86_400.0
"""RecurDyn's bulk conveyor run (the four consignments, 10 mm mesh): 24 h [s] on 4 cores."""
RECURDYN_CONVEYOR_SIMULATED_S = 2.0
"""Its simulated time [s]."""


def recurdyn_wall_s(test: str, simulated_s: float) -> float | None:
    """RecurDyn's wall time [s] for ``test`` scaled linearly to ``simulated_s`` [s], or None
    for a test without a RecurDyn time (the conveyor: see :data:`RECURDYN_CONVEYOR_WALL_S`)."""
    if test == "conveyor":
        return RECURDYN_CONVEYOR_WALL_S * simulated_s / RECURDYN_CONVEYOR_SIMULATED_S
    if test not in RECURDYN_WALL_S:
        return None
    return RECURDYN_WALL_S[test] * simulated_s / PAPER_SIMULATED_S[test]

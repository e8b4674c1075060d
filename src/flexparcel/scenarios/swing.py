"""The swing test as a scenario (paper section 3.2, Fig. 25): ``clamped_length`` of the
consignment's length clamped, released horizontal under gravity, 1.4 s.

Responses [mm]: ``first_swing_mm`` and ``second_swing_mm``, the free end's peak horizontal
excursions past the clamp edge and back
(:func:`~flexparcel.scenarios.consignment_tests.swing_peaks`); a swing the run does not
reach is reported as not reached. Files: see
:mod:`flexparcel.scenarios.consignment_scenario`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from flexparcel.elements.air import check_drag_coefficient
from flexparcel.scenarios.base import Response, ScenarioResult
from flexparcel.scenarios.consignment_scenario import ConsignmentTest, mm_response
from flexparcel.scenarios.consignment_tests import (
    JAWS,
    SWING_NOT_REACHED,
    TestModel,
    TestRun,
    swing_model,
    swing_peaks,
    swing_test,
)
from flexparcel.scenarios.swing_jaws import JawClosing

if TYPE_CHECKING:
    from flexparcel.consignments.snapshot import Snapshot

__all__ = ["SwingScenario", "swing_curve", "CLAMPED_LENGTH"]

CLAMPED_LENGTH = 0.020
"""Clamped length of the paper's swing test [m]."""


class SwingScenario(ConsignmentTest):
    """The swing test; ``clamped_length`` [m] (default the paper's 20 mm); ``jaws``: how the
    clamp closes before the release (None: clamped where the nodes settled); ``air_drag``:
    the envelope's drag coefficient in still air (default 0: none, the paper's model; see
    :func:`flexparcel.consignments.build.add_air_drag`); ``membrane``: the packaging's
    membrane law in the test (:attr:`ConsignmentTest.membrane`; default: the snapshot's)."""

    name = "swing"
    description = "swing test: 20 mm of the length clamped, released horizontal (paper 3.2)"
    t_end = 1.4
    dt_out = 0.005  # the swing takes ~1 s: 5 ms frames draw it smoothly

    def __init__(self, *, clamped_length: float = CLAMPED_LENGTH, stick_model: bool = True,
                 jaws: JawClosing | None = JAWS, air_drag: float = 0.0,
                 membrane: str | None = None, checkpoint: str | Path | None = None):  # fmt: skip
        if not 0.0 < clamped_length < 1.0:
            raise ValueError(f"clamped_length must be in (0, 1) m, got {clamped_length!r}")
        self.air_drag = check_drag_coefficient(air_drag, "air_drag (drag coefficient C_d)")
        self.clamped_length = float(clamped_length)
        self.stick_model = bool(stick_model)
        self.jaws = jaws
        self.set_membrane(membrane)
        self.set_checkpoint(checkpoint)

    def build(self, consignment: Snapshot | Mapping[str, Snapshot],
              parameters: Mapping[str, float | None]) -> TestModel:  # fmt: skip
        snap = self.snapshot(consignment)
        p = self.resolve(parameters, snap.build)
        return swing_model(snap, p, clamped_length=self.clamped_length,
                           stick_model=self.stick_model, jaws=self.jaws,
                           air_drag=self.air_drag)  # fmt: skip

    def _settings(self) -> dict:
        jaws = None if self.jaws is None else asdict(self.jaws)
        return {"clamped_length_m": self.clamped_length, "jaws": jaws,
                "air_drag": self.air_drag}  # fmt: skip

    def _test_run(self, snapshot, parameters, t_end, dt_out, progress) -> TestRun:
        return swing_test(snapshot, parameters, t_end=t_end, dt_out=dt_out, progress=progress,
                          clamped_length=self.clamped_length, stick_model=self.stick_model,
                          jaws=self.jaws, air_drag=self.air_drag,
                          checkpoint=self.checkpoint)  # fmt: skip

    def responses(self, result: ScenarioResult) -> dict[str, Response]:
        x_rel, _, _ = swing_curve(result.record, self.clamped_length)
        first, second = swing_peaks(x_rel)
        return {
            "first_swing_mm": mm_response(
                first, "peak horizontal excursion of the free end past the clamp edge",
                SWING_NOT_REACHED["first_swing_mm"],
            ),
            "second_swing_mm": mm_response(
                second, "peak horizontal excursion of the free end back on its starting side",
                SWING_NOT_REACHED["second_swing_mm"],
            ),
        }  # fmt: skip


def swing_curve(
    run: Any, clamped_length: float = CLAMPED_LENGTH
) -> tuple[np.ndarray, tuple[int, float] | None, tuple[int, float] | None]:
    """The swing's free-end position relative to the clamp edge [m] (k,) and the frames of
    the first and second swing ``(index, response [m])`` (None where there is none), for a
    :class:`~flexparcel.scenarios.consignment_tests.TestRun` of the swing.

    The same quantities as :func:`~flexparcel.scenarios.consignment_tests.swing_test` (mean x
    of the free edge minus the clamp edge, clamp edge = lowest packaging x + ``clamped_length``),
    so the marks sit exactly on the reported responses.
    """
    pos = run.result.positions
    c = run.consignment
    x_clamp = pos[0, c.packaging, 0].min() + clamped_length
    x_rel = pos[:, c.edge, 0].mean(axis=1) - x_clamp
    marks: list[tuple[int, float] | None] = []
    start = 0
    for key, sign in (("first_swing_mm", -1.0), ("second_swing_mm", 1.0)):
        value_mm = run.responses[key]
        if value_mm is None:  # not reached in the run
            marks.append(None)
            continue
        value = value_mm * 1e-3
        hit = np.flatnonzero(np.isclose(sign * x_rel[start:], value, rtol=1e-9, atol=1e-12))
        if value > 0 and hit.size:
            k = start + int(hit[0])
            marks.append((k, value))
            start = k
        else:
            marks.append(None)
    return x_rel, marks[0], marks[1]

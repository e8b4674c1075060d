"""The drop tests as scenarios (paper section 3.2, Fig. 26): released from rest
``drop_height`` (200 mm) above a rigid plate, standing on an edge (``drop-vertical``, with
the edge's line contact) or lying flat (``drop-horizontal``), 0.3 s.

Responses [mm]: ``rebound_mm``, the largest gap between the plate and the consignment's
lowest point after the first touch, as a camera beside the plate sees it (the paper's
Fig. 28; :func:`~flexparcel.scenarios.consignment_tests.camera_clearance`), and
``com_rise_mm``, the rise of the centre of mass in the first bounce above its height at the
first touch (:func:`~flexparcel.scenarios.consignment_tests.com_rise_outcome`), a second
response; either is not reached when the run ends before the touch or before its peak. Files: see
:mod:`flexparcel.scenarios.consignment_scenario`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from flexparcel.elements.air import check_drag_coefficient
from flexparcel.scenarios.base import Response, ScenarioResult
from flexparcel.scenarios.consignment_scenario import ConsignmentTest, mm_response
from flexparcel.scenarios.consignment_tests import (
    TestModel,
    TestRun,
    camera_clearance,
    clearance_peak,
    com_rise_outcome,
    drop_model,
    drop_test,
    drop_touch_radius,
    lowest_point_gap,
)
from flexparcel.scenarios.holding import DropHold

if TYPE_CHECKING:
    from flexparcel.consignments.snapshot import Snapshot

__all__ = [
    "DropScenario",
    "vertical_drop",
    "horizontal_drop",
    "drop_curve",
    "DropCurve",
    "DROP_HEIGHT",
]

DROP_HEIGHT = 0.200
"""Drop height of the paper's tests [m]: the lowest point above the plate at release."""


class DropScenario(ConsignmentTest):
    """A drop test; ``orientation`` "vertical" or "horizontal", ``drop_height`` [m],
    ``air_drag``: the envelope's drag coefficient in still air (default 0: none, the paper's
    model); ``hold``: hold the vertical drop's consignment at rest by its top end under
    gravity before the release (:mod:`flexparcel.scenarios.holding`; default None: released
    from the snapshot as assembled, without gravity); ``membrane``: the packaging's membrane
    law in the test (:attr:`ConsignmentTest.membrane`; default: the snapshot's)."""

    description = "drop test: released from rest 200 mm above a rigid plate (paper 3.2)"
    t_end = 0.3
    dt_out = 0.001  # the impact lasts a few ms

    def __init__(self, orientation: str, *, drop_height: float = DROP_HEIGHT,
                 stick_model: bool = True, air_drag: float = 0.0,
                 hold: DropHold | None = None, membrane: str | None = None,
                 checkpoint: str | Path | None = None):  # fmt: skip
        if orientation not in ("vertical", "horizontal"):
            raise ValueError(f"orientation must be 'vertical' or 'horizontal', got {orientation!r}")
        if not 0.0 < drop_height <= 10.0:
            raise ValueError(f"drop_height must be in (0, 10] m, got {drop_height!r}")
        self.orientation = orientation
        self.name = f"drop-{orientation}"
        self.drop_height = float(drop_height)
        self.stick_model = bool(stick_model)
        self.air_drag = check_drag_coefficient(air_drag, "air_drag (drag coefficient C_d)")
        if hold is not None and orientation != "vertical":
            raise ValueError("hold applies to the vertical drop only")
        self.hold = hold
        self.set_membrane(membrane)
        self.set_checkpoint(checkpoint)

    def build(self, consignment: Snapshot | Mapping[str, Snapshot],
              parameters: Mapping[str, float | None]) -> TestModel:  # fmt: skip
        snap = self.snapshot(consignment)
        return drop_model(snap, self.orientation, self.resolve(parameters, snap.build),
                          drop_height=self.drop_height, stick_model=self.stick_model,
                          air_drag=self.air_drag, hold=self.hold)  # fmt: skip

    def _settings(self) -> dict:
        hold = None if self.hold is None else asdict(self.hold)
        return {"drop_height_m": self.drop_height, "air_drag": self.air_drag, "hold": hold}

    def _test_run(self, snapshot, parameters, t_end, dt_out, progress) -> TestRun:
        return drop_test(snapshot, self.orientation, parameters, t_end=t_end, dt_out=dt_out,
                         drop_height=self.drop_height, progress=progress,
                         stick_model=self.stick_model, air_drag=self.air_drag,
                         hold=self.hold, checkpoint=self.checkpoint)  # fmt: skip

    def responses(self, result: ScenarioResult) -> dict[str, Response]:
        run: TestRun = result.record
        touch = drop_touch_radius(run.consignment, self.orientation)
        rise, rise_why = com_rise_outcome(run.model, run.result, run.consignment, touch)
        gap, gap_why = camera_clearance(run.model, run.result, run.consignment, touch)
        return {
            "rebound_mm": mm_response(
                gap, "largest gap between the plate and the consignment's lowest point after "
                "the first touch (a camera's view, as the paper measured it: Fig. 28)", gap_why),
            "com_rise_mm": mm_response(
                rise, "rise of the centre of mass in the first bounce above its height at the "
                "first touch (a second response, not the paper's)", rise_why),
        }  # fmt: skip

    def _summary_settings(self, result: ScenarioResult) -> dict:
        return {"drop_height_mm": self.drop_height * 1e3}


def vertical_drop(**options: Any) -> DropScenario:
    """``drop-vertical``: standing on its +x edge (KP/BW's glued strip)."""
    return DropScenario("vertical", **options)


def horizontal_drop(**options: Any) -> DropScenario:
    """``drop-horizontal``: lying flat."""
    return DropScenario("horizontal", **options)


@dataclass
class DropCurve:
    """What a drop's response plot draws, on the recorded frames (k of them)."""

    gap: np.ndarray
    """Gap between the plate and the lowest point [m] (k,): the rebound's curve."""
    gap_peak: int | None
    """Frame of the rebound (largest clearance after the first touch), or None."""
    z_centre: np.ndarray
    """Height of the centre of mass [m] (k,)."""
    touch: tuple[float, float] | None
    """First contact: (time [s], centre height [m]), or None without a touch."""
    deepest: int | None
    """Frame of the centre's lowest point after the touch."""
    centre_peak: int | None
    """Frame of the centre's highest point after its lowest (above the touch height), or None."""


def drop_curve(run: TestRun, touch_radius: float | None = None) -> DropCurve:
    """The drop's curves for its plot, measured as the responses are
    (:func:`~flexparcel.scenarios.consignment_tests.camera_clearance` and
    :func:`~flexparcel.scenarios.consignment_tests.com_rise`). ``touch_radius`` [m]: the
    contact radius of the first touch, by default that of the run's orientation
    (:func:`~flexparcel.scenarios.consignment_tests.drop_touch_radius`: standing on its edge,
    the edge's line contact), so that the curve's touch is the response's."""
    res, c = run.result, run.consignment
    if touch_radius is None:
        touch_radius = drop_touch_radius(c, run.test.removeprefix("drop-"))
    gap = lowest_point_gap(res, c, touch_radius)
    gap_peak, _ = clearance_peak(gap)
    ids = c.node_ids
    m = run.model.mass[ids, 0]
    zc = res.positions[:, ids, 2] @ m / m.sum()
    touch = np.flatnonzero(gap <= 0.0)
    if touch.size == 0:
        return DropCurve(gap, None, zc, None, None, None)
    k = int(touch[0])
    if k > 0:
        w = gap[k - 1] / (gap[k - 1] - gap[k])
        t_touch = res.time[k - 1] + w * (res.time[k] - res.time[k - 1])
        z_touch = zc[k - 1] + w * (zc[k] - zc[k - 1])
    else:
        t_touch, z_touch = res.time[0], zc[0]
    kmin = k + int(np.argmin(zc[k:]))
    peak = kmin + int(np.argmax(zc[kmin:]))
    return DropCurve(gap, gap_peak, zc, (float(t_touch), float(z_touch)), kmin,
                     peak if zc[peak] > z_touch else None)  # fmt: skip

"""A consignment's mesh as built, as a snapshot: tests of results, viewers and reports start
from it in seconds instead of assembling."""

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "examples" / "consignment_small.toml"


def raw_snapshot(build):
    """The consignment's mesh as built (not assembled) as a snapshot: a start in seconds."""
    from flexparcel.builder import ModelBuilder
    from flexparcel.consignments.build import add_consignment
    from flexparcel.consignments.snapshot import Snapshot

    b = ModelBuilder()
    add_consignment(b, build)
    model = b.finalize()
    p0 = model.positions0.copy()
    return Snapshot(build, p0, p0.copy(), np.tile(np.eye(3), (len(p0), 1, 1)), {})

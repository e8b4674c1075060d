"""The gusseted bag (KP's construction): a flat-folded mesh whose side walls, unfolded, give
the content's height, closed and consistently oriented; its spec, file and errors."""

from dataclasses import replace

import numpy as np
import pytest

from flexparcel.builder import ModelBuilder
from flexparcel.builder.mesh_checks import check_orientation
from flexparcel.consignments.build import ConsignmentBuild, add_consignment, preset
from flexparcel.consignments.spec import (
    ConsignmentFileError,
    read_consignment_toml,
    write_consignment_toml,
)
from flexparcel.scenarios.envelope import gusseted_envelope

L, W, G, S = 0.35, 0.25, 0.016, 1e-3


@pytest.mark.parametrize("h", [0.025, 0.010, 0.005])
def test_the_folded_bag_is_closed_and_consistently_oriented(h):
    pts, quads, roles = gusseted_envelope(L, W, G, S, h)
    check_orientation([quads])  # raises for an inverted quad, 2 or 4 sheets at an edge
    e = np.sort(np.concatenate([quads[:, [a, (a + 1) % 4]] for a in range(4)]), axis=1)
    _, count = np.unique(e, axis=0, return_counts=True)
    # closed: no free edge; four sheets meet only in the seams' gusset strips
    assert set(count) == {2, 4}
    n_strip_cells = (np.abs(np.unique(pts[:, 1])) >= W / 2 - G - 1e-12).sum() - 2
    assert (count == 4).sum() == 2 * n_strip_cells  # both ends
    assert len(np.unique(quads)) == len(pts)  # every node in an element
    # the top panel's outward normals point up (the rest follow by the orientation check)
    top = quads[roles["top_quads"]]
    n = np.cross(pts[top[:, 1]] - pts[top[:, 0]], pts[top[:, 3]] - pts[top[:, 0]])
    assert np.all(n[:, 2] > 0)
    # panels of nx x ny cells each, four plies of nx x (cells per gusset strip)
    nx, ny = round(L / h), len(np.unique(pts[:, 1])) - 1
    assert len(top) == nx * ny
    assert len(quads) == 2 * nx * ny + 2 * nx * n_strip_cells


@pytest.mark.parametrize("h", [0.025, 0.010])
def test_unfolded_the_side_walls_give_the_content_height(h):
    # The cross-section's developed length (bottom panel, four plies, top panel, each along
    # its own layer) is the filled bag's perimeter 2 w + 4 g; the folded state's small
    # offsets between layers (spacing 1 mm, a tenth of an element or less) lengthen the fold
    # facets by at most spacing^2 / (2 x facet) per fold.
    pts, quads, roles = gusseted_envelope(L, W, G, S, h)
    x_mid = pts[np.argmin(np.abs(pts[:, 0])), 0]
    section = np.abs(pts[:, 0] - x_mid) < 1e-12
    # every edge of the section's quads that lies in the section
    e = np.concatenate([quads[:, [a, (a + 1) % 4]] for a in range(4)])
    e = np.unique(np.sort(e[section[e].all(axis=1)], axis=1), axis=0)
    developed = np.linalg.norm(pts[e[:, 1]] - pts[e[:, 0]], axis=1).sum()
    folds = 6  # four outer folds, two inner
    assert developed == pytest.approx(2 * W + 4 * G, abs=folds * S**2 / (2 * min(G / 2, h)) + 1e-12)
    # layer heights: bottom 0, lower plies s, upper plies 2 s, top 3 s; folds half-way (a
    # ply of one element, G < 1.5 h, has no node between its folds)
    z = np.round(pts[section, 2] / S, 9)
    plies = {1.0, 2.0} if round(G / h) > 1 else set()
    assert set(z) == {0.0, 0.5, 1.5, 2.5, 3.0} | plies
    # the inner folds at the gusset depth from the side edges
    y_in = pts[section & np.isclose(pts[:, 2], 1.5 * S), 1]
    assert np.sort(np.abs(y_in)) == pytest.approx([W / 2 - G] * 2)


def test_roles_of_the_nodes():
    pts, quads, roles = gusseted_envelope(L, W, G, S, 0.010)
    top, bottom, seam = roles["top"], roles["bottom"], roles["seam"]
    assert not set(top) & set(bottom) and not set(seam) & (set(top) | set(bottom))
    assert np.allclose(pts[top, 2], 3 * S) and np.allclose(pts[bottom, 2], 0.0)
    assert np.allclose(np.abs(pts[seam, 0]), L / 2) and np.allclose(pts[seam, 2], 1.5 * S)
    edge = roles["edge"]
    assert np.allclose(pts[edge, 0], L / 2) and np.all(np.diff(pts[edge, 1]) > 0)
    assert set(roles["bottom_layer"]) >= set(bottom) | set(seam)


def test_bad_dimensions_name_the_argument():
    with pytest.raises(ValueError, match=r"gusset_depth must be < width / 2 = 0.125 m"):
        gusseted_envelope(L, W, 0.2, S, 0.01)
    with pytest.raises(ValueError, match=r"spacing must be > 0 m"):
        gusseted_envelope(L, W, G, 0.0, 0.01)


def test_kp_is_a_gusseted_bag_of_table2_width_and_its_walls_fit_the_content():
    spec = preset("KP")
    assert spec.construction == "gusseted"
    build = ConsignmentBuild.of(spec, element_size=0.010)
    length, width = build.flat_size
    assert width == pytest.approx(spec.width_mm * 1e-3)
    # the walls (2 x gusset depth) are higher than the content and its two films
    assert 2 * build.gusset_depth > (spec.content_height_mm * 1e-3 + 2 * build.material.thickness)
    b = ModelBuilder()
    c = add_consignment(b, build)
    model = b.finalize()
    p = model.positions0[c.packaging]
    assert np.ptp(p[:, 1]) == pytest.approx(width) and np.ptp(p[:, 0]) == pytest.approx(length)
    # the opening pulls the top panel up and the bottom down, the seams join the layers
    assert np.allclose(model.positions0[c.top, 2], 3e-3)
    assert np.allclose(model.positions0[c.bottom, 2], 0.0)
    assert np.allclose(np.abs(model.positions0[c.border, 0]), length / 2)
    # the envelope presets are unchanged
    assert preset("KPBW").construction == "envelope"


def test_construction_in_the_consignment_file(tmp_path):
    spec = replace(preset("KP"), id="mine")
    back = read_consignment_toml(write_consignment_toml(spec, tmp_path / "kp.toml"))
    assert back == spec and back.construction == "gusseted"
    # an envelope's file has no construction key (files written before it read the same)
    path = write_consignment_toml(preset("KPBW"), tmp_path / "kpbw.toml")
    assert "construction" not in path.read_text()
    assert read_consignment_toml(path).construction == "envelope"
    bad = path.read_text() + 'construction = "folded"\n'
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(ConsignmentFileError, match=r"construction = 'folded' is invalid "
                       r"\(allowed: envelope\|gusseted\)"):  # fmt: skip
        read_consignment_toml(tmp_path / "bad.toml")

"""The paper's bulk conveyor run (section 4.4, Fig. 35): assembled consignments on a belt with
deflectors, their contacts and friction, the run and its responses.

A scene is a :class:`~flexparcel.scenarios.conveyor.ConveyorScene` (belt and deflectors) plus a
:class:`SceneLayout`: where each consignment lies on the belt (:class:`Placement`: centre x,
y [m] and yaw [deg]). Each consignment starts from its assembled :class:`Snapshot`, moved
rigidly to its placement, lying flat with its lowest packaging node's contact surface
``gap_above_belt`` above the belt, at rest (the belt slides under it from t = 0).

Contacts added (SI units, laws of :mod:`flexparcel.contact.law`):

* packaging shell nodes vs the belt plane (radius: half the packaging thickness): the paper's
  Table 6 packaging-ground law (611 N/mm, 0.591 N s/mm, STEP damping over 0.1 mm) with the
  friction of the packaging's outer surface on the PU belt
  (:mod:`flexparcel.scenarios.friction_pairs`);
* packaging shell nodes vs each deflector's mid-plane mesh (thickness: half the packaging
  thickness plus half the sheet's, so the nodes meet the upstream face), and each deflector's
  tip edge vs the packaging's faces (line contact) and element edges (edge to edge), the same
  thickness, see :func:`~flexparcel.scenarios.conveyor.add_deflector_contact`: the same normal law,
  friction of the surface on X6Cr17 steel;
* packaging vs packaging of two different consignments, both ways (the nodes of each against
  the faces of the other; thickness: the mean of the two half thicknesses): the paper's
  Table 6 packaging-content law (649 N/mm, 0.579 N s/mm) with friction 0.3 (the paper gives no
  packaging-packaging value; ``consignment_friction``). With ``pair_reach`` set, only pairs
  whose footprints start closer than that are paired (see :func:`build_conveyor_model`);
* the content vs the belt plane, with the packaging's belt law, as a backstop: a flexible
  content's nodes (PB) with radius half the packaging thickness (its face-inner nodes do not
  meet the film's faces and can bulge through the film between its nodes), a rigid content's
  rounded box by its corners (its edges can pass between the film's nodes). Resting on its
  packaging a content stays clear of it.

What is not modelled: a content touching a deflector or another consignment directly (only
shell nodes can touch triangle meshes; the content is inside its packaging, which touches
first); the deflector's top and bottom edges against packaging faces and edges (only its
tip edge, which consignments pass round, has line contact, with faces and edge to edge).

Footprints (overlap checks, the default layout): the flat packaging rectangle of the
consignment's build, ``flat_size`` plus KP/BW's glued strip on the +x side, in the
consignment's own frame (its origin is the centre of the flat packaging). The assembled
packaging is smaller (it wraps the content), so a layout that passes the check does not
overlap; this needs only the build, so a layout is checked before any (long) assembly.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numba as nb
import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.consignments.build import (
    GLUED_STRIP_WIDTH,
    Consignment,
    ConsignmentBuild,
    add_consignment,
    add_ground_contact,
    default_packaging_content_law,
)
from flexparcel.consignments.snapshot import Snapshot, place_snapshot
from flexparcel.contact.geometry import segment_segment
from flexparcel.contact.law import ContactLaw, normal_force_packed
from flexparcel.integrate.dynamic import IntegratorOptions
from flexparcel.integrate.linear import cholmod_available
from flexparcel.io.tomlfile import read_toml
from flexparcel.model.checks import finite_number
from flexparcel.model.mesh import shell_edges
from flexparcel.model.model import Model, State
from flexparcel.scenarios.consignment_tests import consignment_options
from flexparcel.scenarios.conveyor import (
    BeltTransfer,
    ConveyorParts,
    ConveyorScene,
    add_conveyor,
    add_deflector_contact,
)
from flexparcel.scenarios.conveyor_groups import GroupSettings, integrate_by_groups
from flexparcel.scenarios.conveyor_responses import ConsignmentResponse, conveyor_responses
from flexparcel.scenarios.friction_pairs import (
    BELT,
    DEFLECTOR,
    FrictionPair,
    surface_material,
    with_friction,
)
from flexparcel.simulate import SimulationResult, simulate

__all__ = [
    "PAPER_CONSIGNMENTS",
    "SCENE_FORMAT",
    "Placement",
    "SceneLayout",
    "SceneFile",
    "SceneFileError",
    "ConveyorModel",
    "ConveyorRun",
    "deflector_node_forces",
    "footprint",
    "paper_conveyor",
    "default_layout",
    "throughput_layout",
    "check_layout",
    "load_scene_file",
    "belt_law",
    "build_conveyor_model",
    "deflector_mean_forces",
    "deflector_crossings",
    "deflector_edge_depths",
    "content_below_belt",
    "run_conveyor",
    "conveyor_options",
    "SUMMARY_NOTES",
]

PAPER_CONSIGNMENTS = ("KPBW", "PB", "KP", "BW")
"""The four consignments of the paper's bulk run (Table 2)."""
SCENE_FORMAT = 1
"""``format_version`` of scene TOML files this module reads."""
DEFAULT_GAP = 0.05
"""Gap between consecutive footprints of the default layout, and of the leading footprint
to the first deflector's root [m]."""
GAP_ABOVE_BELT = 1e-3
"""Default start height of the lowest packaging contact surface above the belt [m]."""
CONSIGNMENT_FRICTION = 0.3
"""Packaging-packaging friction [-] (not given in the paper; as its packaging-content 0.3)."""
# paper Table 6, per point of its 10 mm nodes: per unit area c = 611 N/mm / (10 mm)^2
_GROUND_LAW = dict(c_N_per_mm=611.0, d_Ns_per_mm=0.591, s_max_mm=0.1, reference_spacing_mm=10.0)


@dataclass(frozen=True)
class Placement:
    """Where one consignment starts on the belt.

    Attributes:
        name: label of this consignment in the responses and files (unique in a layout).
        consignment: which consignment (key of the builds/snapshots mapping, e.g. "KPBW").
        x: belt-direction position [m] of the consignment's origin (centre of its flat
            packaging).
        y: cross position [m] (0 = belt centre line).
        yaw_deg: rotation about the vertical [deg] in [-360, 360]; 0 = length along the belt.
        speed: initial velocity along the belt (+x) [m/s] in [0, 10]: 0 = at rest, dropped
            onto the running belt; the belt speed = arriving from an upstream conveyor.
    """

    name: str
    consignment: str
    x: float
    y: float = 0.0
    yaw_deg: float = 0.0
    speed: float = 0.0

    def __post_init__(self) -> None:
        for key in ("name", "consignment"):
            v = getattr(self, key)
            if not isinstance(v, str) or not v.strip():
                raise ValueError(f"Placement.{key} must be a non-empty string, got {v!r}")
        label = f"placement {self.name!r}"
        object.__setattr__(self, "x", finite_number(f"{label}: x", self.x))
        object.__setattr__(self, "y", finite_number(f"{label}: y", self.y))
        yaw = finite_number(f"{label}: yaw_deg", self.yaw_deg)
        if not -360.0 <= yaw <= 360.0:
            raise ValueError(f"{label}: yaw_deg must be in [-360, 360] deg, got {yaw:g}")
        object.__setattr__(self, "yaw_deg", yaw)
        v = finite_number(f"{label}: speed", self.speed)
        if not 0.0 <= v <= 10.0:
            raise ValueError(f"{label}: speed must be in [0, 10] m/s, got {v:g}")
        object.__setattr__(self, "speed", v)

    def rotation(self) -> np.ndarray:
        """Rotation about z by ``yaw_deg``, shape (3, 3)."""
        a = math.radians(self.yaw_deg)
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class SceneLayout:
    """The conveyor and the consignments' start placements.

    Attributes:
        conveyor: belt and deflectors.
        placements: one per consignment, unique names.
        gap_above_belt: start height of the lowest packaging contact surface above the belt
            [m] in [0, 0.05].
    """

    conveyor: ConveyorScene
    placements: tuple[Placement, ...]
    gap_above_belt: float = GAP_ABOVE_BELT

    def __post_init__(self) -> None:
        if not isinstance(self.conveyor, ConveyorScene):
            raise TypeError(f"SceneLayout.conveyor must be a ConveyorScene, got {self.conveyor!r}")
        pl = tuple(self.placements)
        if not pl:
            raise ValueError("SceneLayout.placements must hold at least one placement")
        for p in pl:
            if not isinstance(p, Placement):
                raise TypeError(f"SceneLayout.placements must hold Placements, got {p!r}")
        names = [p.name for p in pl]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(
                f"SceneLayout.placements: duplicate name(s) {dup}; names must be unique"
            )
        object.__setattr__(self, "placements", pl)
        g = finite_number("SceneLayout.gap_above_belt", self.gap_above_belt)
        if not 0.0 <= g <= 0.05:
            raise ValueError(f"SceneLayout.gap_above_belt must be in [0, 0.05] m, got {g:g}")
        object.__setattr__(self, "gap_above_belt", g)

    def to_dict(self) -> dict:
        """JSON-ready copy; keys carry their unit (the scene file's names)."""
        c = self.conveyor
        return {
            "conveyor": {
                "belt_length_m": c.belt_length,
                "belt_width_m": c.belt_width,
                "belt_speed_m_s": c.belt_speed,
                "deflector_angle_deg": c.deflector_angle_deg,
                "deflector_x_m": list(c.deflector_x),
                "centre_gap_m": c.centre_gap,
                "deflector_height_m": c.deflector_height,
                "side_guides": c.side_guides,
                "belt_edge_radius_m": c.belt_edge_radius,
                "transfer": None
                if c.transfer is None
                else {
                    "gap_m": c.transfer.gap,
                    "length_m": c.transfer.length,
                    "speed_m_s": c.transfer.speed,
                },
            },
            "placements": [
                {
                    "name": p.name,
                    "consignment": p.consignment,
                    "x_m": p.x,
                    "y_m": p.y,
                    "yaw_deg": p.yaw_deg,
                    "speed_m_s": p.speed,
                }
                for p in self.placements
            ],  # fmt: skip
            "gap_above_belt_m": self.gap_above_belt,
        }


def footprint(build: ConsignmentBuild) -> tuple[float, float, float, float]:
    """Flat packaging rectangle of ``build`` in its own frame [m]: (x_min, x_max, y_min,
    y_max) (KP/BW's glued strip on the +x side); an upper bound of the assembled one."""
    length, width = build.flat_size
    strip = GLUED_STRIP_WIDTH if build.has_glued_strip else 0.0
    return -0.5 * length, 0.5 * length + strip, -0.5 * width, 0.5 * width


def _corners(build: ConsignmentBuild, p: Placement) -> np.ndarray:
    """Footprint corners of ``build`` at placement ``p`` [m], shape (4, 2)."""
    x0, x1, y0, y1 = footprint(build)
    local = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    r = p.rotation()[:2, :2]
    return local @ r.T + np.array([p.x, p.y])


def _separated(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two convex polygons (or a polygon and a segment), vertices
    (k, 2): True if some edge normal separates them (touching counts as overlap)."""
    for poly in (a, b):
        k = len(poly)
        for i in range(k if k > 2 else 1):
            e = poly[(i + 1) % k] - poly[i]
            n = np.array([-e[1], e[0]])
            pa, pb = a @ n, b @ n
            if pa.max() < pb.min() or pb.max() < pa.min():
                return True
    if len(a) == 2 or len(b) == 2:  # a segment: also test along it
        seg = a if len(a) == 2 else b
        n = seg[1] - seg[0]
        pa, pb = a @ n, b @ n
        if pa.max() < pb.min() or pb.max() < pa.min():
            return True
    return False


def check_layout(layout: SceneLayout, builds: Mapping[str, ConsignmentBuild]) -> None:
    """Raise ``ValueError`` naming the placement unless every placement refers to a known
    consignment, its footprint lies on the belt (0 <= x <= belt_length, |y| <= width / 2),
    clear of every deflector face and of every other footprint."""
    c = layout.conveyor
    corners = {}
    for p in layout.placements:
        if p.consignment not in builds:
            raise ValueError(
                f"placement {p.name!r}: unknown consignment {p.consignment!r}; allowed: "
                f"{', '.join(builds)}"
            )
        q = _corners(builds[p.consignment], p)
        half = 0.5 * c.belt_width
        if q[:, 0].min() < 0.0 or q[:, 0].max() > c.belt_length:
            raise ValueError(
                f"placement {p.name!r}: its footprint spans x = {q[:, 0].min():.3f} .. "
                f"{q[:, 0].max():.3f} m; it must lie on the belt, x in [0, {c.belt_length:g}] m"
            )
        if np.abs(q[:, 1]).max() > half + 1e-12:
            raise ValueError(
                f"placement {p.name!r}: its footprint spans y = {q[:, 1].min():.3f} .. "
                f"{q[:, 1].max():.3f} m; it must lie on the belt, y in [{-half:g}, {half:g}] m"
            )
        for k, g in enumerate(c.deflectors()):
            seg = np.array([g.outer_end[:2], g.tip[:2]])
            if not _separated(q, seg):
                raise ValueError(
                    f"placement {p.name!r}: its footprint overlaps deflector {k} (root at x = "
                    f"{g.root[0]:g} m); place it upstream of the deflector"
                )
        for other, r in corners.items():
            if not _separated(q, r):
                raise ValueError(
                    f"placements {other!r} and {p.name!r} overlap (flat footprints "
                    f"{_extent(r)} and {_extent(q)}); move them apart"
                )
        corners[p.name] = q


def _extent(q: np.ndarray) -> str:
    lo, hi = q.min(axis=0), q.max(axis=0)
    return f"x {lo[0]:.3f}..{hi[0]:.3f} m, y {lo[1]:.3f}..{hi[1]:.3f} m"


def paper_conveyor(
    belt_speed: float = 1.6, deflector_angle_deg: float = 45.0, **kwargs
) -> ConveyorScene:
    """The conveyor of the paper's scene, long enough for the four consignments' queue
    (:func:`default_layout`) upstream of the first deflector: belt 0.6 m wide, first
    deflector root at x = 1.7 m, the second 0.6 m beyond the first one's tip, the belt
    ending 0.5 m beyond the second tip (4.04 m at 45 deg). The paper gives no positions;
    these are our choice. ``kwargs`` go to :class:`ConveyorScene`."""
    width = kwargs.pop("belt_width", 0.6)
    gap = kwargs.pop("centre_gap", 0.03)
    first = kwargs.pop("first_deflector_x", 1.7)
    probe = ConveyorScene(belt_length=50.0, belt_width=width, belt_speed=belt_speed,
                          deflector_angle_deg=deflector_angle_deg, deflector_x=(0.0,),
                          centre_gap=gap)  # fmt: skip
    reach = probe.deflector_reach_x
    x = (first, first + reach + 0.6)
    return ConveyorScene(
        belt_length=min(50.0, x[1] + reach + 0.5), belt_width=width, belt_speed=belt_speed,
        deflector_angle_deg=deflector_angle_deg, deflector_x=x, centre_gap=gap, **kwargs,
    )  # fmt: skip


def default_layout(
    builds: Mapping[str, ConsignmentBuild],
    conveyor: ConveyorScene | None = None,
    *,
    gap: float = DEFAULT_GAP,
    gap_above_belt: float = GAP_ABOVE_BELT,
    speed: float = 0.0,
) -> SceneLayout:
    """A queue on the belt centre line, lengths along the belt: the first consignment of
    ``builds`` (name -> build, e.g. KPBW, PB, KP, BW) ends ``gap`` [m] before the first
    deflector's root, each next one ``gap`` upstream of the previous one, all with initial
    velocity ``speed`` [m/s] along the belt. ``conveyor`` defaults to
    :func:`paper_conveyor`. Raises ``ValueError`` if the queue does not fit between x = 0
    and the first deflector."""
    conveyor = conveyor if conveyor is not None else paper_conveyor()
    if not builds:
        raise ValueError("default_layout: no consignments given")
    if not conveyor.deflector_x:
        raise ValueError("default_layout: the conveyor has no deflector to queue upstream of")
    front = conveyor.deflector_x[0] - gap
    placements = []
    for name, build in builds.items():
        x0, x1, _, _ = footprint(build)
        placements.append(Placement(name, name, front - x1, speed=speed))
        front = front - (x1 - x0) - gap
    tail = front + gap
    if tail < 0.0:
        raise ValueError(
            f"default_layout: the queue needs {conveyor.deflector_x[0] - tail:.3f} m upstream "
            f"of the first deflector, which is at x = {conveyor.deflector_x[0]:g} m; move the "
            "deflectors downstream (deflector_x) or place fewer consignments"
        )
    return SceneLayout(conveyor, tuple(placements), gap_above_belt)


def throughput_layout(
    build: ConsignmentBuild,
    count: int,
    *,
    belt_speed: float = 1.6,
    deflector_angle_deg: float = 45.0,
    gap: float = DEFAULT_GAP,
    belt_width: float = 0.6,
    name: str = "c",
    speed: float = 0.0,
) -> SceneLayout:
    """``count`` copies of ``build`` queued on the centre line (as :func:`default_layout`)
    of a belt made long enough for them: the two deflectors sit after the queue, so every
    copy meets the same conveyor; the copies are named ``{name}0`` (leading) ... Copies
    share the one build (and snapshot) under the key ``name``; ``speed``: initial velocity
    along the belt [m/s]."""
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 200:
        raise ValueError(f"throughput_layout: count must be an integer in [1, 200], got {count!r}")
    x0, x1, _, _ = footprint(build)
    queue = count * (x1 - x0) + count * gap
    conveyor = paper_conveyor(belt_speed, deflector_angle_deg, belt_width=belt_width,
                              first_deflector_x=queue + 0.05)  # fmt: skip
    front = conveyor.deflector_x[0] - gap
    placements = []
    for i in range(count):
        placements.append(Placement(f"{name}{i}", name, front - x1, speed=speed))
        front -= (x1 - x0) + gap
    return SceneLayout(conveyor, tuple(placements))


# ------------------------------------------------------------------------------ scene files


class SceneFileError(ValueError):
    """A scene TOML file is invalid (the message names the file and the key)."""


@dataclass(frozen=True)
class SceneFile:
    """A scene file's content. ``placements`` is empty when the file asks for the default
    layout of ``consignments``; ``consignments`` maps each consignment key to what
    :func:`flexparcel.consignments.userfile.resolve_consignment` takes (a preset name or a
    consignment file path, made absolute)."""

    path: Path
    conveyor: ConveyorScene
    consignments: dict[str, str]
    placements: tuple[Placement, ...] = ()
    gap_above_belt: float = GAP_ABOVE_BELT
    t_end: float | None = None
    """[s], or None for the caller's default."""
    element_size: float | None = None
    """[m], or None for each consignment's own."""
    start_speed: float = 0.0
    """Initial velocity along the belt of the default queue [m/s]."""


_TOP_KEYS = {"format_version", "t_end_s", "element_size_mm", "gap_above_belt_m", "belt",
             "deflectors", "consignments", "consignment", "start_speed_m_s",
             "transfer"}  # fmt: skip
_TRANSFER_KEYS = {"gap_m": "gap", "length_m": "length", "speed_m_s": "speed"}
_BELT_KEYS = {"length_m": "belt_length", "width_m": "belt_width", "speed_m_s": "belt_speed",
              "side_guides": "side_guides", "edge_radius_m": "belt_edge_radius"}  # fmt: skip
_DEFLECTOR_KEYS = {"angle_deg": "deflector_angle_deg", "x_m": "deflector_x",
                   "centre_gap_m": "centre_gap", "height_m": "deflector_height",
                   "thickness_m": "deflector_thickness",
                   "overhang_m": "deflector_overhang"}  # fmt: skip
_PLACEMENT_KEYS = {"name", "consignment", "x_m", "y_m", "yaw_deg", "speed_m_s"}


def load_scene_file(path: str | Path) -> SceneFile:
    """Read and validate a scene TOML file (format: ``examples/conveyor_scene.toml``).

    Raises ``FileNotFoundError`` for a missing file and :class:`SceneFileError` naming the
    file and the key (and the allowed range) for anything invalid. Belt and deflector keys
    not given take :func:`paper_conveyor`'s values (for the given speed and angle)."""
    path = Path(path)
    doc = read_toml(path, SceneFileError, "scene file")

    def fail(msg: str) -> SceneFileError:
        return SceneFileError(f"{path}: {msg}")

    unknown = sorted(set(doc) - _TOP_KEYS)
    if unknown:
        raise fail(f"unknown key(s) {unknown}; allowed: {', '.join(sorted(_TOP_KEYS))}")
    if doc.get("format_version") != SCENE_FORMAT:
        raise fail(f"format_version must be {SCENE_FORMAT}, got {doc.get('format_version')!r}")

    def number(key: str, value: object, lo: float, hi: float, unit: str) -> float:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise fail(f"{key} must be a number in [{lo:g}, {hi:g}] {unit}, got {value!r}")
        if not lo <= value <= hi:
            raise fail(f"{key} must be in [{lo:g}, {hi:g}] {unit}, got {value!r}")
        return float(value)

    def table(key: str, allowed: Mapping[str, str]) -> dict:
        t = doc.get(key, {})
        if not isinstance(t, dict):
            raise fail(f"[{key}] must be a table, got {t!r}")
        bad = sorted(set(t) - set(allowed))
        if bad:
            raise fail(f"[{key}]: unknown key(s) {bad}; allowed: {', '.join(allowed)}")
        return t

    t_end = doc.get("t_end_s")
    if t_end is not None:
        t_end = number("t_end_s", t_end, 1e-3, 10.0, "s")
    size = doc.get("element_size_mm")
    if size is not None:
        size = number("element_size_mm", size, 1.0, 100.0, "mm") * 1e-3
    gap = number("gap_above_belt_m", doc.get("gap_above_belt_m", GAP_ABOVE_BELT), 0.0, 0.05, "m")
    start = number("start_speed_m_s", doc.get("start_speed_m_s", 0.0), 0.0, 10.0, "m/s")
    belt, defl = table("belt", _BELT_KEYS), table("deflectors", _DEFLECTOR_KEYS)
    kw: dict = {}
    for src, allowed in ((belt, _BELT_KEYS), (defl, _DEFLECTOR_KEYS)):
        for key, value in src.items():
            if key == "x_m":
                if not isinstance(value, list) or not value:
                    raise fail(
                        f"[deflectors] x_m must be a non-empty list of numbers, got {value!r}"
                    )
                value = tuple(value)
            kw[allowed[key]] = value
    speed = kw.pop("belt_speed", 1.6)
    angle = kw.pop("deflector_angle_deg", 45.0)
    if "transfer" in doc:
        transfer = table("transfer", _TRANSFER_KEYS)
        try:
            kw["transfer"] = BeltTransfer(**{_TRANSFER_KEYS[k]: v for k, v in transfer.items()})
        except ValueError as exc:
            msg = str(exc).replace("ConveyorScene.transfer.", "")
            for key, field_name in _TRANSFER_KEYS.items():
                msg = msg.replace(f"{field_name} must", f"{key} must", 1)
            raise fail(f"[transfer]: {msg}") from None
    try:
        if "deflector_x" in kw or "belt_length" in kw:
            conveyor = ConveyorScene(belt_speed=speed, deflector_angle_deg=angle, **kw)
        else:
            extra = {k: kw[k] for k in ("belt_width", "centre_gap") if k in kw}
            rest = {k: v for k, v in kw.items() if k not in extra}
            conveyor = paper_conveyor(speed, angle, **extra, **rest)
    except ValueError as exc:
        inv = {v: k for k, v in {**_BELT_KEYS, **_DEFLECTOR_KEYS}.items()}
        msg = str(exc)
        for field_name, key in inv.items():
            msg = msg.replace(f"ConveyorScene.{field_name}", key)
        raise fail(f"[belt]/[deflectors]: {msg}") from None

    def consignment_ref(where: str, value: object) -> str:
        if not isinstance(value, str) or not value.strip():
            raise fail(f"{where} must be a preset name ({', '.join(PAPER_CONSIGNMENTS)}) or a "
                       f"consignment .toml path, got {value!r}")  # fmt: skip
        if value.lower().endswith(".toml"):
            p = Path(value)
            return str(p if p.is_absolute() else (path.parent / p).resolve())
        return value

    names = doc.get("consignments")
    tables = doc.get("consignment")
    if (names is None) == (tables is None):
        raise fail(
            "give either consignments = [...] (the default queue) or [[consignment]] tables "
            "(placements), not both and not neither"
        )
    refs: dict[str, str] = {}
    placements: list[Placement] = []
    if names is not None:
        if not isinstance(names, list) or not names:
            raise fail(f"consignments must be a non-empty list of names, got {names!r}")
        for i, n in enumerate(names):
            ref = consignment_ref(f"consignments[{i}]", n)
            key = Path(ref).stem if ref.lower().endswith(".toml") else ref
            if key in refs:
                raise fail(f"consignments[{i}]: {n!r} appears twice; use [[consignment]] "
                           "tables with distinct names for copies")  # fmt: skip
            refs[key] = ref
    else:
        if not isinstance(tables, list) or not tables:
            raise fail("[[consignment]] must be one or more tables")
        for i, t in enumerate(tables):
            where = f"consignment[{i}]"
            if not isinstance(t, dict):
                raise fail(f"{where} must be a table, got {t!r}")
            bad = sorted(set(t) - _PLACEMENT_KEYS)
            if bad:
                raise fail(f"{where}: unknown key(s) {bad}; allowed: "
                           f"{', '.join(sorted(_PLACEMENT_KEYS))}")  # fmt: skip
            for req in ("consignment", "x_m"):
                if req not in t:
                    raise fail(f"{where}: missing key {req!r}")
            ref = consignment_ref(f"{where}.consignment", t["consignment"])
            key = Path(ref).stem if ref.lower().endswith(".toml") else ref
            if refs.get(key, ref) != ref:
                raise fail(f"{where}.consignment: {key!r} names two different consignments")
            refs[key] = ref
            name = t.get("name", key)
            if not isinstance(name, str) or not name.strip():
                raise fail(f"{where}.name must be a non-empty string, got {name!r}")
            x = number(f"{where}.x_m", t["x_m"], -50.0, 50.0, "m")
            y = number(f"{where}.y_m", t.get("y_m", 0.0), -5.0, 5.0, "m")
            yaw = number(f"{where}.yaw_deg", t.get("yaw_deg", 0.0), -360.0, 360.0, "deg")
            v = number(f"{where}.speed_m_s", t.get("speed_m_s", 0.0), 0.0, 10.0, "m/s")
            placements.append(Placement(name, key, x, y, yaw, v))
        seen: dict[str, int] = {}
        for i, p in enumerate(placements):
            if p.name in seen:
                raise fail(f"consignment[{i}].name {p.name!r} is used by consignment"
                           f"[{seen[p.name]}] too; names must be unique")  # fmt: skip
            seen[p.name] = i
    if tables is not None and "start_speed_m_s" in doc:
        raise fail("start_speed_m_s is for the default queue; give speed_m_s per [[consignment]]")
    return SceneFile(path, conveyor, refs, tuple(placements), gap, t_end, size, start)


# ------------------------------------------------------------------------------ the model


def belt_law(stick_model: bool = True) -> ContactLaw:
    """Packaging-ground normal law of the paper's Table 6 (friction set per pair), with the
    stick model (k_t = c) unless ``stick_model`` is False (see
    :func:`flexparcel.consignments.build.default_packaging_content_law`)."""
    law = ContactLaw.from_paper_units(**_GROUND_LAW)
    return law.with_stick_model() if stick_model else law


@dataclass
class ConveyorModel:
    """A built conveyor scene: the model, its initial state and where everything is."""

    model: Model
    state0: State
    """Every consignment at its placement, at rest, t = 0."""
    layout: SceneLayout
    parts: ConveyorParts
    consignments: dict[str, Consignment]
    """Placement name -> its node ids."""
    laws: dict[str, dict[str, ContactLaw]]
    """Placement name -> {"belt", "deflector"} -> contact law used."""
    consignment_pairs: list[tuple[str, str]] = field(default_factory=list)
    """Pairs of placement names given packaging-packaging contact (each both ways)."""

    def node_sets(self) -> dict[str, np.ndarray]:
        """Placement name -> all node ids of that consignment (for the responses)."""
        return {k: c.node_ids for k, c in self.consignments.items()}

    @staticmethod
    def build(snapshots: Mapping[str, Snapshot], layout: SceneLayout, **kwargs) -> ConveyorModel:
        """:func:`build_conveyor_model`; the group-by-group integration builds its groups'
        sub-scenes with it (so that it needs no import of this module)."""
        return build_conveyor_model(snapshots, layout, **kwargs)


def build_conveyor_model(
    snapshots: Mapping[str, Snapshot],
    layout: SceneLayout,
    *,
    friction_table: Mapping[tuple[str, str], FrictionPair] | None = None,
    consignment_friction: float = CONSIGNMENT_FRICTION,
    pair_reach: float | None = None,
    content_law: ContactLaw | None = None,
) -> ConveyorModel:
    """Build the scene: the conveyor, each placement's consignment (from
    ``snapshots[placement.consignment]``, the mesh and material it was assembled with), the
    contacts of the module docstring, and the initial state.

    ``pair_reach`` [m]: None pairs every two consignments. A number pairs only those whose
    start footprints (bounding circles) are closer than it: the cost of consignment contact
    then grows linearly with a long queue. Pick it above the largest relative travel in the
    run (e.g. belt_speed * t_end: consignments starting at rest never move faster than the
    belt); pairs left out cannot touch (they pass through each other).

    ``content_law``: the packaging-content contact of every consignment (default: the law
    they were assembled with, Table 6's 649 N/mm,
    :func:`~flexparcel.consignments.build.default_packaging_content_law`). A softer law
    trades shape for speed: film nodes of 34 mg on 649 N/mm ring at about 45 us, which is
    where the steps sit. Measured on the four at 25 mm, first 0.05 s: Table 6 703 s (2,098
    steps, 4,625 Newton iterations); c = k_t = 64.9 N/mm, damping kept: 264 s (495 steps,
    1,646 iterations), centroids within 0.8 mm in x and 0.5 mm in z of the stiff run (KP's
    centroid 0.47 mm lower: its film settles deeper on the box).
    """
    builds = {k: s.build for k, s in snapshots.items()}
    check_layout(layout, builds)
    if pair_reach is not None:
        pair_reach = finite_number("pair_reach", pair_reach)
        if pair_reach < 0.0:
            raise ValueError(f"pair_reach must be >= 0 m or None, got {pair_reach:g}")
    mu = finite_number("consignment_friction", consignment_friction)
    if not 0.0 <= mu <= 2.0:
        raise ValueError(f"consignment_friction must be in [0, 2], got {mu:g}")
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    parts = add_conveyor(b, layout.conveyor)
    cons: dict[str, Consignment] = {}
    laws: dict[str, dict[str, ContactLaw]] = {}
    ground = belt_law()
    for p in layout.placements:
        build = snapshots[p.consignment].build
        c = add_consignment(b, build, content_law=content_law)
        cons[p.name] = c
        surface = surface_material(build.spec.packaging_material)
        lb = with_friction(ground, surface, BELT, friction_table)
        ld = with_friction(ground, surface, DEFLECTOR, friction_table)
        laws[p.name] = {"belt": lb, "deflector": ld}
        for belt in parts.belt_planes:  # packaging, and content as a backstop
            add_ground_contact(b, c, belt, lb)
        add_deflector_contact(b, parts, c.packaging, ld, shell_half_thickness=c.contact_radius)
    pp_law = replace(default_packaging_content_law(), mu_static=mu, mu_dynamic=mu)
    names = [p.name for p in layout.placements]
    centre = {p.name: np.array([p.x, p.y]) for p in layout.placements}
    radius = {}
    for p in layout.placements:
        x0, x1, y0, y1 = footprint(builds[p.consignment])
        radius[p.name] = math.hypot(max(-x0, x1), max(-y0, y1))
    pairs = []
    for i, a in enumerate(names):
        for bn in names[i + 1 :]:
            gap = float(np.linalg.norm(centre[a] - centre[bn])) - radius[a] - radius[bn]
            if pair_reach is not None and gap > pair_reach:
                continue
            ca, cb = cons[a], cons[bn]
            h = 0.5 * (ca.contact_radius + cb.contact_radius)
            b.add_face_contact(ca.packaging, cb.packaging, pp_law, thickness=h)
            b.add_face_contact(cb.packaging, ca.packaging, pp_law, thickness=h)
            pairs.append((a, bn))
    model = b.finalize()
    state = None
    for p in layout.placements:
        c = cons[p.name]
        snap = snapshots[p.consignment]
        first = int(c.node_ids.min())
        state = place_snapshot(
            snap, model, rotation=p.rotation(), offset=(p.x, p.y, 0.0),
            lowest_z=c.contact_radius + layout.gap_above_belt, first_node=first, state=state,
        )  # fmt: skip
        state.velocities[c.node_ids, 0] = p.speed
    assert state is not None
    return ConveyorModel(model, state, layout, parts, cons, laws, pairs)


def deflector_node_forces(cm: ConveyorModel, result: SimulationResult) -> np.ndarray:
    """Normal force [N] of each deflector on every node at the recorded frames, shape
    (deflectors, k, n): recomputed from the recorded positions and velocities with each
    consignment's deflector law, per packaging node over a face rectangle: penetration
    s = h - distance to the face plane (h = half the packaging thickness), rate s' = -v . normal,
    pressure p = max(c s^m_s + damping, R_df c s^m_s) [N/m^2] (paper eqs. 1-6, per unit area)
    times the node's tributary area, read from the model's node-face contact sets (the area
    they multiply the law by). Nodes behind the sheet's mid-plane (half
    ``deflector_thickness`` behind the face) or off the rectangle do not count. Peaks between
    frames are missed: it samples the force every output interval."""
    area = np.zeros(cm.model.node_count)
    for cs in cm.model.contact_sets:
        if cs.kind == "node_face":  # packaging on the deflector faces carries every node's area
            area[cs.node] = cs.area
    pos, vel = np.asarray(result.positions), np.asarray(result.velocities)
    deflectors = cm.parts.deflectors
    out = np.zeros((len(deflectors), *pos.shape[:2]))
    for name, c in cm.consignments.items():
        law = cm.laws[name]["deflector"].packed()
        h = c.contact_radius
        p, v = pos[:, c.packaging], vel[:, c.packaging, :3]
        for d, g in enumerate(deflectors):
            dist, on = g.over_face(p, below=h)
            s = h - dist
            on &= (s > 0.0) & (dist > -0.5 * cm.parts.scene.deflector_thickness)  # upstream
            rate = -(v @ g.normal)
            k, i = np.nonzero(on)
            node = c.packaging[i]
            out[d, k, node] = _law_pressures(s[k, i], rate[k, i], law) * area[node]
    return out


@nb.njit(cache=True)
def _law_pressures(s, rate, law):
    """The packed law's normal pressure [N/m^2] at each penetration ``s`` [m] and rate
    ``rate`` [m/s], shape (m,)."""
    out = np.empty(s.size)
    for q in range(s.size):
        out[q] = normal_force_packed(s[q], rate[q], law)[0]
    return out


def deflector_mean_forces(
    cm: ConveyorModel, result: SimulationResult
) -> dict[str, np.ndarray] | None:
    """Force [N] of all deflectors on each consignment, the mean over each output interval:
    placement name -> shape (k,), the magnitude of the deflectors' impulse on its nodes
    between frames i - 1 and i over their time apart (0 at frame 0, which ends no interval).
    Normal force and friction together. From the impulse the run records
    (:attr:`~flexparcel.simulate.SimulationResult.monitored_impulses`; the deflector contacts
    are monitored), so it is the load a force gauge averaging over ``dt_out`` reads, whatever
    the contact's stiffness and the step sizes, where a sample at the frame
    (:func:`deflector_node_forces`) catches the contact law's spikes or misses them. None
    for a result without the record."""
    if result.monitored_impulses is None:
        return None
    out = {}
    for name, c in cm.consignments.items():
        mean = result.mean_monitored_forces(c.node_ids)
        out[name] = np.concatenate([[0.0], np.linalg.norm(mean, axis=1)])
    return out


def deflector_crossings(
    cm: ConveyorModel, result: SimulationResult, depth: float = 0.01
) -> dict[str, float | None]:
    """First recorded time [s] at which a packaging node of each consignment lies behind a
    deflector, or None: behind the sheet's mid-plane by less than ``depth`` [m] (> 0), with
    its projection on the face rectangle. Packaging comes from upstream and leaves past the
    tip, so a node there has gone through the sheet, a sign that the contact failed (see
    :mod:`flexparcel.scenarios.conveyor`), or round the tip's edge (a film folding round
    it). Placement name -> time."""
    depth = finite_number("depth", depth)
    if depth <= 0.0:
        raise ValueError(f"depth must be > 0 m, got {depth:g}")
    t = np.asarray(result.time)
    positions = np.asarray(result.positions)
    half = 0.5 * cm.parts.scene.deflector_thickness
    out: dict[str, float | None] = {}
    for name, c in cm.consignments.items():
        p = positions[:, c.packaging]  # (k, m, 3)
        hit = np.zeros(len(t), dtype=bool)
        for g in cm.parts.deflectors:
            dist, on = g.over_face(p)
            behind = -dist - half  # beyond the mid-plane [m]
            hit |= (on & (behind > 0.0) & (behind < depth)).any(axis=1)
        out[name] = float(t[np.argmax(hit)]) if hit.any() else None
    return out


@nb.njit(cache=True)
def _deepest_edge_pair(frames, edges, segs, reach):
    """Smallest distance [m] between any edge (E, 2) and any segment (S, 2) over the frames
    (k, n, 3), and its frame; pairs whose midpoints are farther apart than their half
    lengths plus ``reach`` are skipped (their distance exceeds ``reach``)."""
    best = np.inf
    where = -1
    for k in range(frames.shape[0]):
        x = frames[k]
        for j in range(segs.shape[0]):
            q0 = x[segs[j, 0]]
            q1 = x[segs[j, 1]]
            qm = 0.5 * (q0 + q1)
            qh = 0.5 * math.sqrt(np.sum((q1 - q0) ** 2))
            for e in range(edges.shape[0]):
                p0 = x[edges[e, 0]]
                p1 = x[edges[e, 1]]
                pm = 0.5 * (p0 + p1)
                ph = 0.5 * math.sqrt(np.sum((p1 - p0) ** 2))
                if math.sqrt(np.sum((pm - qm) ** 2)) > ph + qh + reach:
                    continue
                d = segment_segment(p0, p1, q0, q1)[2]
                if d < best:
                    best = d
                    where = k
    return best, where


def deflector_edge_depths(cm: ConveyorModel, result: SimulationResult) -> dict[str, dict]:
    """How deep each consignment's packaging element edges came into the deflectors' free
    vertical edges (the tips near the centre line and the outer ends beyond the belt edge):
    the largest ``depth = h - d`` over the recorded frames, with d the distance between an
    element edge and an edge segment of the sheet's mid-plane, and h the contact thickness
    (:meth:`~flexparcel.scenarios.conveyor.ConveyorParts.deflector_contact_thickness`).

    A packaging edge pressed on a deflector edge penetrates its contact by a fraction of a
    millimetre (the law's load over its stiffness). ``depth`` close to ``h`` means that the
    element chords through the sheet's edge, what the edge-to-edge contact of
    :func:`~flexparcel.scenarios.conveyor.add_deflector_contact` is there to prevent (a
    result to distrust there). Between frames deeper approaches are missed. Placement name
    -> {"depth_m", "thickness_m", "time_s", "edge" ("tip 1", "end 2", ... by deflector,
    upstream first)}; ``depth_m``, ``time_s`` and ``edge`` are None if no packaging edge came
    within h of a deflector edge."""
    t = np.asarray(result.time)
    frames = np.ascontiguousarray(np.asarray(result.positions, dtype=np.float64))
    parts = cm.parts
    lines = []
    for j, (tip, end) in enumerate(zip(parts.deflector_tips, parts.deflector_ends, strict=True)):
        for kind, ids in (("tip", tip), ("end", end)):
            ids = np.asarray(ids, dtype=np.int64)
            lines.append((f"{kind} {j + 1}", np.column_stack([ids[:-1], ids[1:]])))
    out: dict[str, dict] = {}
    for name, c in cm.consignments.items():
        h = parts.deflector_contact_thickness(c.contact_radius)
        keep = np.zeros(cm.model.node_count, dtype=bool)
        keep[c.packaging] = True
        edges = shell_edges(cm.model.cells, keep)
        best = {"depth_m": None, "thickness_m": h, "time_s": None, "edge": None}
        for label, segs in lines:
            d, k = _deepest_edge_pair(frames, edges, segs, h)
            if d < h and (best["depth_m"] is None or h - d > best["depth_m"]):
                best.update(depth_m=float(h - d), time_s=float(t[k]), edge=label)
        out[name] = best
    return out


def content_below_belt(cm: ConveyorModel, result: SimulationResult) -> dict[str, dict]:
    """How far each consignment's content came below the belt surface while over a belt: the
    largest depth [m] of its lowest surface point under z = 0 over the recorded frames (a
    rigid box's lowest rounded corner, a flexible content's lowest node less its contact
    radius), counted only where that point lies over a belt's top face (a consignment that
    fell off the end or an edge is not below the belt). The content rests on its packaging
    on the belt, so it should stay above the surface; the contact's own scale, the belt
    law's s_max (``damping_depth``, Table 6's 0.1 mm: the penetration at full damping), is
    reported as ``limit_m``.
    Between frames deeper moments are missed. Placement name -> {"depth_m", "limit_m",
    "time_s"}; ``depth_m`` and ``time_s`` are None if the content never went below z = 0."""
    from flexparcel.elements.rotations import rotation_exp

    t = np.asarray(result.time)
    pos = np.asarray(result.positions)
    scene = cm.parts.scene
    m = cm.model
    out: dict[str, dict] = {}
    for name, c in cm.consignments.items():
        if c.content_body is not None:
            i = int(np.flatnonzero(m.rigid_nodes == c.content_body)[0])
            half, radius = m.rigid_half_inner[i], float(m.rigid_radius[i])
            corners = []  # the lowest inner corner in each frame: its sphere is lowest
            for v, x in zip(np.asarray(result.rotation_vectors)[:, c.content_body],
                            pos[:, c.content_body], strict=True):  # fmt: skip
                r = rotation_exp(v)
                corners.append(x + r @ (np.where(r[2] > 0.0, -1.0, 1.0) * half))
            corners = np.array(corners)
            lowest = corners[:, None, 2] - radius
            xy = corners[:, None, :2]
        else:
            lowest = pos[:, c.content_nodes, 2] - c.contact_radius  # (k, m)
            xy = pos[:, c.content_nodes, :2]
        over = np.zeros(lowest.shape, dtype=bool)
        for x0, x1, _ in scene.belt_spans():
            over |= (xy[..., 0] >= x0) & (xy[..., 0] <= x1)
        over &= np.abs(xy[..., 1]) <= 0.5 * scene.belt_width
        depth = np.where(over, -lowest, -np.inf).max(axis=1)  # (k,)
        law = cm.laws[name]["belt"]
        row = {"depth_m": None, "limit_m": law.damping_depth, "time_s": None}
        if depth.max() > 0.0:
            k = int(np.argmax(depth))
            row.update(depth_m=float(depth[k]), time_s=float(t[k]))
        out[name] = row
    return out


SUMMARY_NOTES = {
    "deflector_crossings": "per consignment, the first time [s] a packaging node lies behind "
    "a deflector (contact failed); null: never, the wanted outcome",
    "deflector_edge_depths": "per consignment, how far [m] packaging element edges came "
    "inside the contact thickness of a deflector's tip or end edge; null: never within it",
    "content_below_belt": "per consignment, how far [m] the content's lowest surface went "
    "below the belt surface while over a belt (limit_m: the belt law's s_max); "
    "null: never below it",
    "friction": "[mu_static, mu_dynamic] of each contact pair [-]",
    "consignments": "per consignment: keys carry their unit (_s, _m, _deg, _N); its notes "
    "say why a value is null",
}
"""The ``notes`` of a conveyor run's ``responses.json``: units and the meaning of null of
the keys without a unit suffix."""


@dataclass
class ConveyorRun:
    """A finished conveyor run."""

    conveyor_model: ConveyorModel
    result: SimulationResult
    responses: dict[str, ConsignmentResponse]
    wall_s: float
    """Wall time of the integration alone [s]."""
    build_wall_s: float
    """Wall time of building the model [s]."""

    def summary(self) -> dict:
        """``responses.json`` content: per-consignment responses, ``simulated_s``,
        ``wall_s``, ``steps``, layout, model size and :func:`deflector_crossings`."""
        res, cm = self.result, self.conveyor_model
        st = res.stats
        sim = float(res.time[-1] - res.time[0])
        return {
            "scenario": "conveyor",
            "consignments": {k: r.to_dict() for k, r in self.responses.items()},
            "simulated_s": sim,
            "wall_s": float(self.wall_s),
            "build_wall_s": float(self.build_wall_s),
            "simulated_s_per_wall_s": sim / self.wall_s if self.wall_s > 0 else None,
            "steps": int(st.get("steps", 0)),
            "rejected_steps": int(st.get("rejected_steps", 0)),
            "newton_iterations": int(st.get("newton_iterations", 0)),
            "node_count": int(cm.model.node_count),
            "dof_count": int(cm.model.dof_count),
            "consignment_contact_pairs": [list(p) for p in cm.consignment_pairs],
            # name kept for the benchmark's JSON; the unit and the meaning of null in notes
            "deflector_crossings": deflector_crossings(cm, res),
            "deflector_edge_depths": deflector_edge_depths(cm, res),
            "content_below_belt": content_below_belt(cm, res),
            "layout": cm.layout.to_dict(),
            "friction": {
                k: {part: [law.mu_static, law.mu_dynamic] for part, law in v.items()}
                for k, v in cm.laws.items()
            },
            "notes": dict(SUMMARY_NOTES),
        }


def conveyor_options() -> IntegratorOptions:
    """Integrator options of the conveyor scenes: the consignment tests' options
    (:func:`~flexparcel.scenarios.consignment_tests.consignment_options`: rho_inf = 0.5,
    ``impact_limit="rigid"``, ``error_estimate="smooth"``) without Newton relaxation, and
    with a slow regrowth of the step cap after a Newton failure (``newton_cap_growth`` 1.02).

    Measured on the four paper consignments at 25 mm from their snapshots (first 0.01 s, the
    same machine load): PB's film nodes, slipping on their content with a slip direction
    that flips between Newton iterations, limit Newton's reach to about 27 us, which stays
    put; with the default regrowth (1.05 per step) a step failed
    every 6 steps, each failure costing as much as 5-8 accepted steps: 463 steps, 73 failures,
    1,263 Newton iterations, 181 s; with 1.02: 406 steps, 34 failures, 781 iterations, 116 s.
    KP/BW, KP and BW alone (0.05 s): 92.8 s and 92.5 s, the same. Newton relaxation (the
    consignment tests' choice), both with 1.02, over the first 0.02 s of the four: 243 s
    (372 steps, 1,670 iterations) against 224 s (811 steps, 1,559 iterations) without; it was
    24 % slower on KP/BW, KP and BW alone, so it stays off.

    Linear solver: CHOLMOD (:class:`~flexparcel.integrate.linear.CholmodSolver`, the
    ``fast`` extra that ``make`` installs) where cvxopt is installed, its symbolic analysis
    held across the Newton matrices of one sparsity pattern; else SuperLU per block of the
    matrix (one per consignment or group of touching ones) in single precision refined to a
    double-precision solution (``"superlu-blocks-mixed"``). Measured on each paper consignment
    alone on the belt at 25 mm from its shipped snapshot, Table 6 content contact, first
    0.01 s, one model (:func:`run_conveyor` on :func:`default_layout` of that consignment
    alone, with ``options=replace(conveyor_options(), linear_solver=...)``): PB 52 s
    against 100 s (factorisation 20.5 s against 66.1 s; its 3,030-DOF block with the hex
    content fills to 1.16 million LU entries), KP 32 s against 46 s, BW 18 s against 25 s;
    the same steps within 7 %, the centroids within 0.3 um. PB, the slowest consignment, sets
    the pace of a grouped run. The conveyor tests (tests/test_conveyor*.py) took 140 s
    against 189 s. The stick tangent for slipping contacts (``friction_tangent="stick"``) is
    not used: it halved the first 0.01 s of the four (SuperLU) but took 776 s against 703 s
    over the first 0.05 s (839 steps of 6.5 Newton iterations against 2,098 of 2.2), its
    linear convergence using up the Newton tolerance (BW's centroid 0.7 mm apart at
    0.05 s). Nor is the symmetric one (``"symmetric"``, the swing's and the drops' choice):
    from the 2 s run's state at 1.82 s (the four consignments touching each other and the
    deflectors, one model, 0.01 s) it took 727 steps and 3,005 Newton iterations against 539
    and 1,931 with the consistent tangent (its contact state reset at the start, the same for
    both; the likely reason, not isolated: films that slide under a changing pressure, whose
    F_N coupling it leaves out). Reusing the last factorisation as a GMRES preconditioner
    (``krylov_reuse``) does not pay: on PB it refactorised at 1,594 of 1,606 Newton
    iterations, the contact set changing between them."""
    return replace(
        consignment_options(),
        newton_relaxation=False,
        newton_cap_growth=1.02,
        linear_solver="cholmod" if cholmod_available() else "superlu-blocks-mixed",
    )


def run_conveyor(
    snapshots: Mapping[str, Snapshot],
    layout: SceneLayout,
    t_end: float = 2.0,
    *,
    dt_out: float = 0.01,
    friction_table: Mapping[tuple[str, str], FrictionPair] | None = None,
    pair_reach: float | None = None,
    options: IntegratorOptions | None = None,
    progress: Callable[[float, float], None] | None = None,
    jam_time: float = 0.3,
    checkpoint: str | Path | None = None,
    checkpoint_only: bool = False,
    content_law: ContactLaw | None = None,
    groups: GroupSettings | None = None,
) -> ConveyorRun:
    """Build the scene (:func:`build_conveyor_model`), simulate ``t_end`` [s] in (0, 10]
    recording every ``dt_out`` [s], and compute each consignment's responses
    (:func:`~flexparcel.scenarios.conveyor_responses.conveyor_responses`, with the
    deflectors' mean force over each output interval, :func:`deflector_mean_forces`, as its
    contact forces).

    Integrator defaults: :func:`conveyor_options`. ``checkpoint``: a ``.npz`` path the run
    saves itself to about once a minute and resumes from (see :func:`flexparcel.simulate`);
    with ``checkpoint_only`` the run is what that file holds so far (no stepping).
    ``content_law``: see :func:`build_conveyor_model`. ``groups``: integrate consignments
    that cannot touch as separate models in parallel workers
    (:func:`~flexparcel.scenarios.conveyor_groups.integrate_by_groups`); None: the whole
    scene as one model.
    """
    t_end = finite_number("t_end", t_end)
    if not 0.0 < t_end <= 10.0:
        raise ValueError(f"t_end must be in (0, 10] s, got {t_end:g}")
    dt_out = finite_number("dt_out", dt_out)
    if not 0.0 < dt_out <= t_end:
        raise ValueError(f"dt_out must be in (0, t_end = {t_end:g}] s, got {dt_out:g}")
    w0 = time.perf_counter()
    cm = build_conveyor_model(snapshots, layout, friction_table=friction_table,
                              pair_reach=pair_reach, content_law=content_law)  # fmt: skip
    build_wall = time.perf_counter() - w0
    opts = options or conveyor_options()
    if groups is None:
        res = simulate(cm.model, t_end, dt_out=dt_out, options=opts, state=cm.state0,
                       progress=progress, checkpoint=checkpoint,
                       checkpoint_only=checkpoint_only)  # fmt: skip
    else:
        # a plain dict: the workers are spawned, and a read-only mapping does not pickle
        table = None if friction_table is None else dict(friction_table)
        build = {"friction_table": table, "pair_reach": pair_reach,
                 "content_law": content_law}  # fmt: skip
        res = integrate_by_groups(cm, snapshots, t_end, dt_out=dt_out, options=opts,
                                  build_kwargs=build, settings=groups, progress=progress,
                                  checkpoint=checkpoint,
                                  checkpoint_only=checkpoint_only)  # fmt: skip
    wall = res.stats["wall_s"]["total"]  # with the wall time before a resumption
    forces = deflector_mean_forces(cm, res)
    responses = conveyor_responses(
        res, cm.node_sets(), layout.conveyor, contact_forces=forces,
        jam_time=jam_time,
    )  # fmt: skip
    return ConveyorRun(cm, res, responses, wall, build_wall)

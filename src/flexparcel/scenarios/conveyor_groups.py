"""A conveyor scene integrated group by group: consignments that cannot touch each other are
stepped as separate models, each with its own step size, in parallel worker processes.

Why: the consignments of a scene interact only through packaging-packaging contact
(:func:`~flexparcel.scenarios.conveyor_scene.build_conveyor_model`); the belt and the
deflectors are prescribed. Integrated as one model, every consignment takes the step that the
hardest one needs at that moment (PB's film pressed on a deflector sets 0.1 ms steps for
all four) and a Newton failure anywhere rejects the step everywhere. Apart, each takes its
own steps, and the groups run on separate cores (design brief section 2: "exploit that
separate consignments only couple through contact").

How (a co-simulation with exact coupling, synchronised at every output frame):

* A *group* is a set of placements integrated as one model: the conveyor plus those
  consignments, built by :func:`build_conveyor_model` on the sub-layout, with every
  contact of the full scene among its members. At t = 0 each placement is its own group
  unless it starts within merge distance of another.
* All groups advance to the next output frame. At each frame, for every two groups whose
  consignments have contact in the full scene, the gap between their packagings (the
  nearest node of either to a face of the other, as their contact measures it,
  :func:`mesh_gap`) of each two of their consignments A, B is compared with
  ``reach + lookahead dt_out (|u_A - u_B| + s_A + s_B) + merge_slack`` (lookahead 2 by
  default; u: mean velocity of a packaging's nodes, s: their largest speed about it; reach:
  the two packaging contact radii, more than their face contact thickness); a bounding box
  test first skips the pairs that are far apart. Groups within it are merged
  before the next frame: the merged model takes the members' states and integrator
  histories (algorithmic accelerations, stick springs and anchors, matched by node and
  contact), so no contact between them can open before they are one model.
* Each frame is checked as well: two groups closer than ``reach`` (they could touch) mean
  the prediction missed; both are then rewound to the frame before, merged, and that frame
  is integrated again together (``stats["groups"]["rewinds"]``).
* A merged group splits again into the parts that are farther apart than that merge gap
  plus ``split_slack``; each part takes its share of the group's state and history.

What differs from one model: each group's step sizes and error estimate are its own, so the
frames agree with a one-model run within the integrator's tolerances, not bit for bit.
Moving a group from one worker to another (load balancing: the groups are dealt to the
workers largest measured cost first) restores its integrator history exactly, so the
result does not depend on the worker count. The checkpoint holds every group's state and
history at a frame, and a resumed run continues bit for bit.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import time as _time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numba as nb
import numpy as np

from flexparcel.contact.broadphase import point_triangle_candidates
from flexparcel.contact.geometry import point_triangle
from flexparcel.integrate.dynamic import (
    CONTACT_HISTORY,
    SOLVER_HISTORY,
    GeneralizedAlpha,
    IntegratorOptions,
    Stats,
)
from flexparcel.model.mesh import surface_triangles
from flexparcel.model.model import State
from flexparcel.simulate import SimulationResult, Stepper, simulate

__all__ = ["GroupSettings", "GroupStepper", "integrate_by_groups", "box_gap", "mesh_gap"]


@dataclass(frozen=True)
class GroupSettings:
    """How :func:`integrate_by_groups` runs.

    Attributes:
        workers: worker processes (>= 1; 1 runs the groups in this process, one after
            another: the groups still take their own steps).
        threads_per_worker: numba threads of each worker while several are at work (>= 1);
            a worker alone at work in a frame, or with more than 80 % of the recent work,
            gets ``workers`` times as many.
        merge_slack: extra gap [m] >= 0 below which two groups are merged.
        lookahead: output intervals >= 0 of approach at the frame's relative speed bound
            that the merge gap allows for (0: merge only within ``merge_slack``, and rewind
            whatever comes within reach).
        split_slack: a merged group splits again into the parts that are farther apart
            than the merge gap plus this [m] >= 0 (hysteresis against merging back at once).
        rebalance_frames: frames between load-balancing checks (>= 1).
    """

    workers: int = 2
    threads_per_worker: int = 1
    merge_slack: float = 0.005
    lookahead: float = 2.0
    split_slack: float = 0.01
    rebalance_frames: int = 10

    def __post_init__(self) -> None:
        for key in ("workers", "threads_per_worker", "rebalance_frames"):
            v = getattr(self, key)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"GroupSettings.{key} must be an integer >= 1, got {v!r}")
        for key, unit in (("merge_slack", " m"), ("lookahead", ""), ("split_slack", " m")):
            v = getattr(self, key)
            if not (isinstance(v, int | float) and np.isfinite(v) and v >= 0.0):
                raise ValueError(f"GroupSettings.{key} must be >= 0{unit}, got {v!r}")


def box_gap(lo_a: np.ndarray, hi_a: np.ndarray, lo_b: np.ndarray, hi_b: np.ndarray) -> float:
    """Euclidean distance [m] between two axis-aligned boxes (corners (3,)); 0 if they
    overlap."""
    d = np.maximum(0.0, np.maximum(lo_b - hi_a, lo_a - hi_b))
    return float(np.sqrt(d @ d))


@nb.njit(cache=True)
def _closest(pairs, points, tris, pos, limit):
    """Smallest point-triangle distance [m] over candidate pairs (K, 2), at most ``limit``."""
    best = limit
    for k in range(pairs.shape[0]):
        t = tris[pairs[k, 1]]
        d = abs(point_triangle(points[pairs[k, 0]], pos[t[0]], pos[t[1]], pos[t[2]])[0])
        best = min(best, d)
    return best


def mesh_gap(pos: np.ndarray, a: tuple, b: tuple, limit: float) -> float:
    """Distance [m] between two packagings as their contact sees it: the nearest node of
    either to a face of the other (``a``, ``b``: (node ids (N,), triangles (M, 3)) into
    ``pos`` (n, 3)), capped at ``limit`` (the broad phase looks no farther)."""
    best = float(limit)
    for (nodes, _), (_, tris) in ((a, b), (b, a)):
        pts = np.ascontiguousarray(pos[nodes])
        pairs = point_triangle_candidates(pts, 0.0, tris, pos, limit)
        if pairs.size:
            best = min(best, float(_closest(pairs, pts, tris, pos, limit)))
    return best


# ------------------------------------------------------------------ one group's integration


# the integrator's monitored-contact arrays (GeneralizedAlpha.history), per node
_MONITOR_KEYS = ("monitored_impulse", "monitored_force", "monitored_alg")
_ROWS = "rows"
"""Prefix of the exported row identities of each contact set's history."""


class _Group:
    """One group's model, integrator and state (in a worker). :meth:`export` carries its
    state and integrator history in full-scene numbering, keyed by node and contact, so that
    a model of other members can take them over (``exports`` of the constructor)."""

    def __init__(self, setup: dict, names: tuple[str, ...], exports: list[dict] | None):
        layout = setup["layout"]
        sub = replace(layout, placements=tuple(p for p in layout.placements if p.name in names))
        cm = setup["build_model"](setup["snapshots"], sub, **setup["build"])
        self.names = names
        self.model = cm.model
        # sub-model node -> full-scene node: the conveyor's nodes come first in both
        full_ids = setup["full_ids"]
        n_conv = min(int(c.node_ids.min()) for c in cm.consignments.values())
        self.full = np.empty(cm.model.node_count, np.int64)
        self.full[:n_conv] = np.arange(n_conv)
        for name, c in cm.consignments.items():
            self.full[c.node_ids] = full_ids[name]
        self.integ = GeneralizedAlpha(cm.model, setup["options"])
        # identity of each contact set's history rows in full-scene numbering, so that a
        # model of other members takes over the rows it shares (they do not change)
        self._rows = {}
        for cs in self.integ.model.contact_sets:
            rows = cs.history_rows(self.full)
            if rows is not None:
                self._rows[cs.key] = rows
        self._key_arrays = {f"{_ROWS}.{k}": v for k, v in self._rows.items()}
        m = cm.model
        self.wall = 0.0  # wall time of the last advance [s]
        sched = list(m.schedules) + [m.gravity_schedule]
        self._breaks = sorted({float(b) for s in sched for b in s.breakpoints()})
        if exports is None:  # the scene's initial state, at rest or where the caller put it
            s0 = setup["state0"]
            f = self.full
            self.state = State(s0.time, s0.positions[f].copy(), s0.rotations[f].copy(),
                               s0.velocities[f].copy(), s0.accelerations[f].copy())  # fmt: skip
            self.integ.initialize(self.state)
        else:
            self._take(exports)
        self._start = self.export()

    # the integrator scalars (GeneralizedAlpha._HISTORY_SCALARS) a merged model starts from:
    # the smallest step and Newton cap of its members, a fresh rate measurement
    def _merged_scalars(self, exports: list[dict]) -> np.ndarray:
        names = GeneralizedAlpha._HISTORY_SCALARS
        s = np.array([e["scalars"] for e in exports])
        out = np.array(self.integ.history()["scalars"], dtype=float)
        for k, name in enumerate(names):
            if name in ("h", "_h_cap"):
                out[k] = s[:, k].min()
            elif name in ("_last_rate", "_impact_w2"):
                out[k] = s[:, k].max()
        return out

    def _take(self, exports: list[dict]) -> None:
        """State and history from the members' exports (all at one time)."""
        m = self.model
        self.integ._alg = np.zeros((m.node_count, 6))  # restore_history replaces it
        hist = self.integ.history()
        # node arrays: scattered into full-scene numbering, then gathered for this model
        n_full = 1 + max(int(e["nodes"].max()) for e in exports)
        node = {}
        keys = ("positions", "rotations", "velocities", "accelerations", "alg", "fc_prev",
                *(k for k in _MONITOR_KEYS if k in hist))  # fmt: skip
        for key in keys:
            full = np.full((n_full, *exports[0][key].shape[1:]), np.nan)
            for e in exports:
                full[e["nodes"]] = e[key]
            node[key] = full[self.full]
            if np.isnan(node[key]).any():
                raise ValueError(f"group {self.names}: the exports do not cover its nodes")
        hist["alg"], hist["fc_prev"] = node["alg"], node["fc_prev"]
        hist.update({k: node[k] for k in _MONITOR_KEYS if k in hist})
        pos, rot, vel, acc = (node[k] for k in ("positions", "rotations", "velocities",
                                                 "accelerations"))  # fmt: skip
        self._take_contact_history(hist, exports)
        if len(exports) == 1 and tuple(map(str, exports[0]["members"])) == self.names:
            # the same group elsewhere (moved, resumed): it goes on exactly
            hist["scalars"] = exports[0]["scalars"]
            hist["stat_counts"] = exports[0]["stat_counts"]
            hist["stat_wall"] = exports[0]["stat_wall"]
            hist.update({k: v for k, v in exports[0].items() if k.startswith(f"{SOLVER_HISTORY}.")})
        else:  # merged or split: a fresh step controller state and statistics
            hist["scalars"] = self._merged_scalars(exports)
        self.integ.restore_history(hist)
        self.state = State(float(exports[0]["time"]), pos, rot, vel, acc)

    def _take_contact_history(self, hist: dict, exports: list[dict]) -> None:
        """Fill the contact sets' history rows of ``hist`` that the exports hold, matched
        by row identity; a row no export has (a set between two former groups) stays empty."""
        held: dict = {}
        for e in exports:
            for key in e:
                if not key.startswith(f"{_ROWS}."):
                    continue
                set_key = key[len(_ROWS) + 1 :]
                prefix = f"{CONTACT_HISTORY}.{set_key}."
                arrays = {k[len(prefix) :]: e[k] for k in e if k.startswith(prefix)}
                for name, arr in arrays.items():
                    held.update(((row, name), v) for row, v in zip(e[key], arr, strict=True))
        for set_key, rows in self._rows.items():
            prefix = f"{CONTACT_HISTORY}.{set_key}."
            for key in [k for k in hist if k.startswith(prefix)]:
                name = key[len(prefix) :]
                for i, row in enumerate(rows):
                    v = held.get((row, name))
                    if v is not None:
                        hist[key][i] = v

    def export(self) -> dict:
        """State and integrator history at the current time, in full-scene numbering."""
        s, hist = self.state, self.integ.history()
        out = {
            "time": np.array(s.time),
            "members": np.array(self.names, dtype=str),
            "nodes": self.full.copy(),
            "positions": s.positions.copy(),
            "rotations": s.rotations.copy(),
            "velocities": s.velocities.copy(),
            "accelerations": s.accelerations.copy(),
            **self._key_arrays,
        }
        out.update({k: v for k, v in hist.items()})
        return out

    def advance(self, t_out: float) -> dict:
        """Step to ``t_out`` [s]; returns the frame in full-scene numbering."""
        self._start = self.export()
        w0 = _time.perf_counter()
        s = self.state
        while s.time < t_out - 1e-12 * max(1.0, abs(t_out)):
            nxt = [b for b in self._breaks if s.time + 1e-12 < b < t_out]
            s = self.integ.step(s, nxt[0] if nxt else t_out)
        s.time = float(t_out)
        self.state = s
        self.wall = _time.perf_counter() - w0
        return self.frame()

    def frame(self) -> dict:
        s = self.state
        imp = self.integ.monitored_impulse
        return {
            "nodes": self.full,
            "positions": s.positions.copy(),
            "rotations": s.rotations.copy(),
            "velocities": s.velocities.copy(),
            "monitored_impulse": None if imp is None else imp.copy(),
            "wall": self.wall,
            "stats": asdict(self.integ.stats),
        }

    def rewind(self) -> dict:
        """The export from before the last :meth:`advance`."""
        return self._start


class _Worker:
    """The groups one process owns, driven by commands (see :func:`_serve`)."""

    def __init__(self, setup: dict) -> None:
        self.setup = setup
        self.groups: dict[int, _Group] = {}

    def handle(self, cmd: str, arg):
        if cmd == "create":  # (key, names, exports or None) -> frame
            key, names, exports = arg
            self.groups[key] = _Group(self.setup, tuple(names), exports)
            return self.groups[key].frame()
        if cmd == "advance":  # (keys, t_out, numba threads or None) -> {key: frame}
            keys, t_out, threads = arg
            if threads is not None:
                import numba

                numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            return {k: self.groups[k].advance(t_out) for k in keys}
        if cmd == "export":  # key -> export now
            return self.groups[arg].export()
        if cmd == "rewind":  # key -> export from before the last advance
            return self.groups[arg].rewind()
        if cmd == "drop":
            del self.groups[arg]
            return None
        raise ValueError(f"unknown worker command {cmd!r}")


def _serve(conn, setup: dict, threads: int) -> None:
    """Worker process: answer commands until told to stop; errors go back as text."""
    import numba

    from flexparcel.io.lifetime import die_with_parent

    die_with_parent()  # a coordinator killed with SIGKILL takes its workers along
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    worker = _Worker(setup)
    while True:
        cmd, arg = conn.recv()
        if cmd == "stop":
            break
        try:
            conn.send(("ok", worker.handle(cmd, arg)))
        except Exception as e:  # noqa: BLE001 - every failure goes back to the coordinator
            conn.send(("error", (type(e).__name__, str(e), traceback.format_exc())))
    conn.close()


class _LocalHandle:
    """A worker in this process (``workers=1``)."""

    def __init__(self, setup: dict) -> None:
        self.worker = _Worker(setup)
        self._reply = None

    def send(self, cmd: str, arg) -> None:
        self._reply = self.worker.handle(cmd, arg)

    def recv(self):
        return self._reply

    def close(self) -> None:
        pass


class _ProcessHandle:
    """A worker process; :meth:`send` does not wait, so several work at once."""

    def __init__(self, setup: dict, threads: int) -> None:
        ctx = mp.get_context("spawn")  # no fork of a process that may hold thread pools
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child, setup, threads), daemon=True)
        self.proc.start()
        child.close()

    def send(self, cmd: str, arg) -> None:
        self.conn.send((cmd, arg))

    def recv(self):
        while not self.conn.poll(1.0):
            if not self.proc.is_alive():  # died without a word (killed, out of memory)
                raise RuntimeError(
                    f"conveyor group worker (pid {self.proc.pid}) exited with code "
                    f"{self.proc.exitcode} without answering"
                )
        status, value = self.conn.recv()
        if status == "error":
            name, msg, tb = value
            from flexparcel.integrate.errors import ConvergenceError

            if name == "ConvergenceError":
                raise ConvergenceError(msg)
            raise RuntimeError(f"conveyor group worker failed: {name}: {msg}\n{tb}")
        return value

    def close(self) -> None:
        try:
            self.conn.send(("stop", None))
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(timeout=10)
        if self.proc.is_alive():
            self.proc.terminate()


# ------------------------------------------------------------------ the coordinator


@dataclass
class _GroupInfo:
    names: tuple[str, ...]
    worker: int
    nodes: np.ndarray  # full-scene node ids of the members' consignments
    costs: list = field(default_factory=list)  # wall per frame [s]
    estimate: float | None = None  # expected wall per frame before the first one [s]
    stats: dict = field(default_factory=dict)


def _components(items: list, links: list) -> list[list]:
    """Connected components of ``items`` under the pairs ``links`` (union-find), each in
    the order of ``items``."""
    parent = {k: k for k in items}

    def find(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for a, b in links:
        parent[find(a)] = find(b)
    comp: dict = {}
    for k in items:
        comp.setdefault(find(k), []).append(k)
    return list(comp.values())


def _add_stats(total: dict, st: dict) -> None:
    for k, v in st.items():
        if k == "wall_s":
            w = total.setdefault("wall_s", {})
            for p, x in v.items():
                w[p] = w.get(p, 0.0) + x
        else:
            total[k] = total.get(k, 0) + v


def _export_arrays(prefix: str, e: dict) -> dict:
    return {f"{prefix}{k}": np.asarray(v) for k, v in e.items()}


def _import_arrays(prefix: str, arrays: dict) -> dict:
    return {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}


def integrate_by_groups(
    cm,
    snapshots: Mapping,
    t_end: float,
    *,
    dt_out: float,
    options: IntegratorOptions,
    build_kwargs: dict,
    settings: GroupSettings | None = None,
    progress: Callable[[float, float], None] | None = None,
    checkpoint: str | Path | None = None,
    checkpoint_interval_s: float = 60.0,
    checkpoint_only: bool = False,
) -> SimulationResult:
    """Integrate the scene ``cm`` (a :class:`~flexparcel.scenarios.conveyor_scene.ConveyorModel`
    built from ``snapshots`` with ``build_kwargs``) from its ``state0`` to ``t_end`` [s]
    group by group (module docstring), recording every ``dt_out`` [s]: :func:`simulate`
    with a :class:`GroupStepper`.

    Returns a :class:`~flexparcel.simulate.SimulationResult` of the full scene's model (frames
    in its node numbering, energies of the full model). ``stats`` sums the groups'
    integrator statistics and adds ``groups``: the groups at the end, the merges (time and
    members), rewinds and the wall time of each worker. ``checkpoint``: as for
    :func:`flexparcel.simulate` (same file format; a one-model checkpoint is refused).
    """
    stepper = GroupStepper(cm, snapshots, options, build_kwargs, settings, dt_out)
    return simulate(cm.model, t_end, dt_out=dt_out, state=cm.state0, progress=progress,
                    checkpoint=checkpoint, checkpoint_interval_s=checkpoint_interval_s,
                    checkpoint_only=checkpoint_only, stepper=stepper)  # fmt: skip


class GroupStepper(Stepper):
    """Steps a conveyor scene from frame to frame as groups of consignments in worker
    processes, merging groups before they can touch and splitting them once apart (module
    docstring). Driven by :func:`flexparcel.simulate.simulate`."""

    mode = "groups"

    def __init__(self, cm, snapshots: Mapping, options: IntegratorOptions, build_kwargs: dict,
                 settings: GroupSettings | None, dt_out: float) -> None:  # fmt: skip
        self.settings = settings or GroupSettings()
        self.options = options
        self.dt_out = float(dt_out)
        model = cm.model
        cons = cm.consignments
        self.names = [p.name for p in cm.layout.placements]
        self.can_touch = {frozenset(p) for p in cm.consignment_pairs}
        self.radius = {k: c.contact_radius for k, c in cons.items()}
        self.full_ids = {k: c.node_ids for k, c in cons.items()}
        # each placement's packaging surface (its faces as its contact sets see them): the
        # only part that touches another consignment
        self.surf = {}
        for k, c in cons.items():
            inside = np.zeros(model.node_count, bool)
            inside[c.packaging] = True
            tri = surface_triangles(model.cells, inside)
            self.surf[k] = (np.asarray(c.packaging), np.ascontiguousarray(tri))
        setup = {
            "snapshots": dict(snapshots),
            "layout": cm.layout,
            "build": build_kwargs,
            "options": options,
            "full_ids": self.full_ids,
            "state0": cm.state0,
            # the scene's own builder (a module-level function: the spawned workers import it)
            "build_model": type(cm).build,
        }
        n = self.settings.workers
        self.handles = (
            [_LocalHandle(setup)]
            if n == 1
            else [_ProcessHandle(setup, self.settings.threads_per_worker) for _ in range(n)]
        )
        self.groups: dict[int, _GroupInfo] = {}
        self.retired: dict = {}
        self.merges: list = []
        self.splits: list = []
        self.rewinds = 0
        self.worker_wall = [0.0] * n
        self._next_key = 0
        self.cur: State | None = None
        # the monitored (deflector) contacts' impulse on each consignment node; the
        # conveyor's own nodes are in every group's model and keep 0 here
        self.impulse = np.zeros((model.node_count, 3)) if model.has_monitored_contact else None
        self._consignment_node = np.zeros(model.node_count, bool)
        self._consignment_node[np.concatenate(list(self.full_ids.values()))] = True

    # ---------------------------------------------------------------- the Stepper protocol
    def options_header(self) -> dict:
        return json.loads(json.dumps(asdict(self.options)))

    def begin(self, state: State) -> State:
        self.cur = state.copy()
        for n in self.names:
            self._create((n,), None)
        self._merge(self._close_pairs(margin=True), "export")
        return self.cur

    def resume(self, state: State, history: dict[str, np.ndarray]) -> State:
        self.cur = state.copy()
        info = json.loads(str(history["groups_json"]))
        self.retired = info["retired"]
        self.merges = info["merges"]
        self.splits = info["splits"]
        self.rewinds = info["rewinds"]
        n = self.settings.workers
        self.worker_wall = (info["worker_wall"] + [0.0] * n)[:n]
        for i, members in enumerate(info["groups"]):
            self._create(tuple(members), [_import_arrays(f"g{i}_", history)])
        return self.cur

    def advance(self, state: State, t_out: float, progress) -> State:
        todo = sorted(self.groups)
        while todo:
            self._advance_groups(todo, t_out)
            # two groups within reach: the prediction missed; do this frame again together
            missed = self._close_pairs(margin=False)
            todo = []
            if missed:
                self.rewinds += 1
                todo = self._merge(missed, "rewind")  # merged at the frame before
        self.cur.time = float(t_out)
        if progress is not None:
            progress(self.cur.time, t_out)
        return self.cur

    def after_frame(self, state: State, index: int) -> None:
        self._merge(self._close_pairs(margin=True), "export")
        self._split()
        if (index + 1) % self.settings.rebalance_frames == 0:
            self._rebalance()

    def history(self) -> dict[str, np.ndarray]:
        info = {
            "groups": [list(g.names) for g in self.groups.values()],
            "retired": self.retired, "merges": self.merges, "splits": self.splits,
            "rewinds": self.rewinds, "worker_wall": self.worker_wall,
        }  # fmt: skip
        hist = {"groups_json": np.array(json.dumps(info))}
        for i, k in enumerate(self.groups):
            h = self.handles[self.groups[k].worker]
            h.send("export", k)
            hist.update(_export_arrays(f"g{i}_", h.recv()))
        return hist

    def monitored_impulse(self) -> np.ndarray | None:
        return self.impulse

    def statistics(self) -> dict:
        total = dict(self.retired)
        for g in self.groups.values():
            _add_stats(total, g.stats)
        base = asdict(Stats())
        for k, v in base.items():
            total.setdefault(k, v)
        total["wall_s"] = {**base["wall_s"], **total.get("wall_s", {})}
        # each final group's own statistics (since it was formed; its wall is its stepping)
        per_group = [
            {"members": list(g.names), "steps": int(g.stats["steps"]),
             "newton_iterations": int(g.stats["newton_iterations"]),
             "rejected_steps": int(g.stats["rejected_steps"]),
             "wall_s": float(sum(g.costs))}
            for g in self.groups.values()
        ]  # fmt: skip
        total["groups"] = {
            "final": [list(g.names) for g in self.groups.values()],
            "per_group": per_group,
            "merges": self.merges,
            "splits": self.splits,
            "rewinds": self.rewinds,
            "workers": self.settings.workers,
            "worker_busy_s": self.worker_wall,
        }
        return total

    def close(self) -> None:
        for h in self.handles:
            h.close()

    # ---------------------------------------------------------------- groups and workers
    def _advance_groups(self, todo: list[int], t_out: float) -> None:
        """Advance the groups ``todo`` to ``t_out``, each worker its own at once."""
        groups, n_workers = self.groups, self.settings.workers
        busy = sorted({groups[k].worker for k in todo})
        t_start = {w: _time.perf_counter() for w in busy}
        # a worker alone at work, or one with most of the recent work (the others idle for
        # most of the frame), gets the others' cores for its tangent assembly
        share = {w: self._load(w) for w in busy}
        total_load = sum(share.values())
        for w in busy:
            keys = [k for k in todo if groups[k].worker == w]
            lead = len(busy) == 1 or share[w] > 0.8 * total_load
            threads = None if n_workers == 1 else (
                self.settings.threads_per_worker * (n_workers if lead else 1))  # fmt: skip
            self.handles[w].send("advance", (keys, t_out, threads))
        for w in busy:
            for k, fr in self.handles[w].recv().items():
                groups[k].costs.append(fr["wall"])
                groups[k].stats = fr["stats"]
                self._store(fr)
            self.worker_wall[w] += _time.perf_counter() - t_start[w]

    def _nodes_of(self, members) -> np.ndarray:
        return np.concatenate([self.full_ids[n] for n in members])

    def _load(self, worker: int) -> float:
        """Recent wall per frame of a worker's groups [s]; node counts before any frame."""

        def cost(g: _GroupInfo) -> float:
            if g.costs:
                return float(np.mean(g.costs[-5:]))
            return g.nodes.size if g.estimate is None else g.estimate

        return sum(cost(g) for g in self.groups.values() if g.worker == worker)

    def _create(self, members, exports, worker=None) -> int:
        key = self._next_key
        self._next_key += 1
        if worker is None:
            worker = min(range(self.settings.workers), key=self._load)
        h = self.handles[worker]
        h.send("create", (key, tuple(members), exports))
        fr = h.recv()
        self._store_impulse(fr)
        self.groups[key] = _GroupInfo(
            tuple(members), worker, self._nodes_of(members), stats=fr["stats"]
        )
        return key

    def _take_out(self, key: int, how: str) -> dict:
        g = self.groups.pop(key)
        h = self.handles[g.worker]
        h.send(how, key)
        e = h.recv()
        h.send("drop", key)
        h.recv()
        return e

    def _retire(self, key: int, how: str) -> dict:
        _add_stats(self.retired, self.groups[key].stats)
        return self._take_out(key, how)

    def _store(self, fr: dict) -> None:
        ids = fr["nodes"]
        self.cur.positions[ids] = fr["positions"]
        self.cur.rotations[ids] = fr["rotations"]
        self.cur.velocities[ids] = fr["velocities"]
        self._store_impulse(fr)

    def _store_impulse(self, fr: dict) -> None:
        """Take a group frame's monitored impulse on its consignments' nodes."""
        if self.impulse is not None:
            own = self._consignment_node[fr["nodes"]]
            self.impulse[fr["nodes"][own]] = fr["monitored_impulse"][own]

    def _motion(self) -> dict:
        """Per placement: packaging bounding box, mean velocity u and largest speed about it."""
        out = {}
        for k, (nodes, _) in self.surf.items():
            x = self.cur.positions[nodes]
            v = self.cur.velocities[nodes, :3]
            u = v.mean(axis=0)
            out[k] = (x.min(axis=0), x.max(axis=0), u, float(np.sqrt(((v - u) ** 2).sum(1)).max()))
        return out

    def _near(self, mot, m: str, n: str, margin: bool, extra: float = 0.0) -> bool:
        """Whether placements m and n are within their merge gap (margin: the lookahead
        and slack added; else the contact reach alone) plus ``extra``."""
        lm, hm, um, sm = mot[m]
        ln, hn, un, sn = mot[n]
        lim = self.radius[m] + self.radius[n] + extra
        if margin:
            rel = float(np.linalg.norm(um - un)) + sm + sn
            lim += self.settings.lookahead * self.dt_out * rel + self.settings.merge_slack
        if box_gap(lm, hm, ln, hn) >= lim:  # boxes apart: the meshes are too
            return False
        return mesh_gap(self.cur.positions, self.surf[m], self.surf[n], lim) < lim

    def _close_pairs(self, margin: bool):
        """Pairs of group keys that must be one model (margin: predicted for the next
        frame; else: already within reach)."""
        mot = self._motion()
        out = []
        keys = sorted(self.groups)
        for i, a in enumerate(keys):
            for b in keys[i + 1 :]:
                if any(frozenset((m, n)) in self.can_touch and self._near(mot, m, n, margin)
                       for m in self.groups[a].names for n in self.groups[b].names):  # fmt: skip
                    out.append((a, b))
        return out

    def _split(self) -> None:
        """Split merged groups into the parts that are farther apart than the merge gap plus
        ``split_slack``: each part takes the group's state and history (its own nodes and
        contacts), and steps on its own again."""
        mot = self._motion()
        for key in [k for k, g in self.groups.items() if len(g.names) > 1]:
            g = self.groups[key]
            linked = [(m, n) for i, m in enumerate(g.names) for n in g.names[i + 1 :]
                      if frozenset((m, n)) in self.can_touch
                      and self._near(mot, m, n, True, self.settings.split_slack)]  # fmt: skip
            parts = _components(list(g.names), linked)
            if len(parts) < 2:
                continue
            cost = float(np.mean(g.costs[-5:])) if g.costs else None
            size = g.nodes.size
            e = self._retire(key, "export")
            self.splits.append({"time": float(e["time"]), "parts": [list(p) for p in parts]})
            for members in parts:
                k2 = self._create(tuple(members), [e])
                if cost is not None:  # dealt by its share of the group's cost
                    self.groups[k2].estimate = cost * self.groups[k2].nodes.size / size

    def _merge(self, pairs, how: str) -> list[int]:
        made = []
        comps = [sorted(c) for c in _components(list(self.groups), pairs) if len(c) > 1]
        for comp in comps:
            members = tuple(n for n in self.names if any(n in self.groups[k].names for k in comp))
            # the members' recent cost: a merged group is dealt by it, not by its size
            cost = sum(float(np.mean(self.groups[k].costs[-5:])) for k in comp
                       if self.groups[k].costs)  # fmt: skip
            exports = [self._retire(k, how) for k in comp]
            self.merges.append({"time": float(exports[0]["time"]), "members": list(members)})
            made.append(self._create(members, exports))
            self.groups[made[-1]].estimate = cost
        return made

    def _rebalance(self) -> None:
        """Deal the groups to the workers largest recent cost first; move those whose
        worker changes if that shortens the slowest worker by 10 %."""
        groups, n_workers = self.groups, self.settings.workers
        frames = self.settings.rebalance_frames
        cost = {k: float(np.mean(g.costs[-frames:])) for k, g in groups.items() if g.costs}
        if len(cost) != len(groups) or n_workers == 1:
            return
        now = [0.0] * n_workers
        for k, g in groups.items():
            now[g.worker] += cost[k]
        new = [0.0] * n_workers
        assign = {}
        for k in sorted(cost, key=cost.get, reverse=True):
            w = int(np.argmin(new))
            assign[k] = w
            new[w] += cost[k]
        if max(new) > 0.9 * max(now):
            return
        for k, w in assign.items():
            if groups[k].worker != w:
                g = groups[k]
                e = self._take_out(k, "export")
                key = self._create(g.names, [e], worker=w)
                groups[key].costs = g.costs

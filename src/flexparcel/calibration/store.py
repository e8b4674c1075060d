"""The study store: one SQLite file holding every run and every stage result of a study.

Tables (schema version :data:`SCHEMA_VERSION`):

``meta``           key/value: schema version, creation time, flexparcel version, study name.
``runs``           one row per distinct simulation, keyed by :func:`run_key` (a SHA-256 of the
                   simulator, its version, its setup and the exact parameter values): status
                   (``pending``/``running``/``done``/``failed``), attempts, responses, last error,
                   timings, worker, code version.
``attempts``       one row per started attempt of a run, with its outcome and error text, so a
                   failure is never silently overwritten by a later success.
``design_points``  (stage, experiment, position) -> run key: which runs make up which design.
                   Several design points may share a run (nothing is run twice).
``results``        (stage, experiment) -> JSON payload of a stage's results (screening tables,
                   surrogate hyper-parameters, the optimum, validation).

Every change is one SQLite transaction (``BEGIN IMMEDIATE ... COMMIT``, journal synced), so a
kill at any instant leaves either the old or the new state, never a half-written run. Only the
controlling process writes; workers return results to it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import socket
import sqlite3
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = ["SCHEMA_VERSION", "StudyStore", "StudyStoreError", "RunSpec", "cost_key", "run_key"]

#: Version of the store layout; a store written with another version is refused.
SCHEMA_VERSION = 1

_STATUSES = ("pending", "running", "done", "failed")

_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE runs (
    run_key TEXT PRIMARY KEY,
    simulator TEXT NOT NULL,
    simulator_version TEXT NOT NULL,
    setup_json TEXT NOT NULL,
    params_json TEXT NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('pending', 'running', 'done', 'failed')),
    attempts INTEGER NOT NULL DEFAULT 0,
    responses_json TEXT,
    error TEXT,
    created REAL NOT NULL,
    started REAL,
    finished REAL,
    wall_s REAL,
    worker TEXT,
    code_version TEXT
);
CREATE TABLE attempts (
    run_key TEXT NOT NULL REFERENCES runs(run_key),
    attempt INTEGER NOT NULL,
    started REAL NOT NULL,
    finished REAL,
    status TEXT NOT NULL,
    error TEXT,
    worker TEXT,
    PRIMARY KEY (run_key, attempt)
);
CREATE TABLE design_points (
    stage TEXT NOT NULL,
    experiment TEXT NOT NULL,
    position INTEGER NOT NULL,
    run_key TEXT NOT NULL REFERENCES runs(run_key),
    PRIMARY KEY (stage, experiment, position)
);
CREATE TABLE results (
    stage TEXT NOT NULL,
    experiment TEXT NOT NULL,
    payload_json TEXT NOT NULL,
    updated REAL NOT NULL,
    PRIMARY KEY (stage, experiment)
);
CREATE INDEX runs_status ON runs(status);
"""


class StudyStoreError(ValueError):
    """A study store that cannot be used (wrong schema version, not a store, in use)."""


def _canonical(value):
    """JSON-ready canonical form: floats as their shortest round-trip repr, keys sorted."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"non-finite value {value!r} cannot be hashed")
        return repr(value)
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in sorted(value.items())}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    raise TypeError(f"cannot hash a value of type {type(value).__name__}")


@dataclass(frozen=True)
class RunSpec:
    """What one simulation is: simulator name and version, fixed setup, parameter values."""

    simulator: str
    simulator_version: str
    setup: Mapping
    params: Mapping[str, float]

    @property
    def key(self) -> str:
        return run_key(self.simulator, self.simulator_version, self.setup, self.params)


def run_key(simulator: str, version: str, setup: Mapping, params: Mapping[str, float]) -> str:
    """SHA-256 hex digest identifying a simulation.

    Parameter values enter exactly (``repr`` of the float), so a point regenerated from the same
    seeded design gets the same key and is found in the store instead of being run again.
    """
    params = {k: float(v) for k, v in params.items()}
    payload = json.dumps(
        {
            "simulator": simulator,
            "version": str(version),
            "setup": _canonical(dict(setup)),
            "params": _canonical(params),
        },
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(payload.encode()).hexdigest()


def _dumps(obj) -> str:
    return json.dumps(obj, sort_keys=True, allow_nan=True)


def cost_key(run: Mapping) -> tuple[str, str]:
    """What sets a run's cost: its simulator and setup (the fidelity level's element size,
    the simulated time...), from a store row or anything with those two fields."""
    return str(run["simulator"]), _dumps(run["setup"])


class StudyStore:
    """A SQLite study file (created on first use).

    Opening an existing file checks that it is a flexparcel study store of schema version
    :data:`SCHEMA_VERSION` and raises :class:`StudyStoreError` otherwise.
    """

    def __init__(self, path: str | os.PathLike, *, create: bool = True):
        self.path = Path(path)
        exists = self.path.exists() and self.path.stat().st_size > 0
        if not exists and not create:
            raise FileNotFoundError(f"study store {self.path} does not exist")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # isolation_level=None: transactions are explicit (BEGIN IMMEDIATE in transaction()).
        self._conn = sqlite3.connect(str(self.path), isolation_level=None, timeout=30.0)
        self._conn.row_factory = sqlite3.Row
        try:
            self._conn.execute("PRAGMA synchronous=FULL")
            self._conn.execute("PRAGMA foreign_keys=ON")
            if exists:
                self._check_schema()
            else:
                self._create()
        except sqlite3.DatabaseError as exc:
            self._conn.close()
            raise StudyStoreError(f"{self.path} is not a flexparcel study store ({exc})") from exc
        except StudyStoreError:
            self._conn.close()
            raise
        self._lock_fd: int | None = None

    # -- setup -------------------------------------------------------------------------------

    def _create(self) -> None:
        from flexparcel._version import __version__

        with self.transaction() as c:
            for stmt in filter(None, (s.strip() for s in _SCHEMA.split(";"))):
                c.execute(stmt)
            c.executemany(
                "INSERT INTO meta(key, value) VALUES (?, ?)",
                [
                    ("schema_version", str(SCHEMA_VERSION)),
                    ("created", repr(time.time())),
                    ("flexparcel_version", __version__),
                ],
            )

    def _check_schema(self) -> None:
        tables = {r[0] for r in self._conn.execute("SELECT name FROM sqlite_master")}
        if "meta" not in tables or "runs" not in tables:
            raise StudyStoreError(f"{self.path} is an SQLite file but not a flexparcel study store")
        row = self._conn.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
        version = row[0] if row else "unknown"
        if version != str(SCHEMA_VERSION):
            raise StudyStoreError(
                f"study store {self.path} has schema version {version}, this flexparcel reads "
                f"version {SCHEMA_VERSION}; use a new store file (or the flexparcel version "
                "that wrote it)"
            )

    def close(self) -> None:
        self.release_lock()
        self._conn.close()

    def __enter__(self) -> StudyStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @contextlib.contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """An immediate (write-locking) transaction: committed on success, rolled back on error."""
        self._conn.execute("BEGIN IMMEDIATE")
        try:
            yield self._conn
        except BaseException:
            self._conn.execute("ROLLBACK")
            raise
        self._conn.execute("COMMIT")

    # -- campaign lock ---------------------------------------------------------------------------

    def acquire_lock(self) -> None:
        """Take the advisory campaign lock (a ``flock`` on ``<store>.lock``).

        Only one process may execute runs of a store at a time, otherwise one campaign would
        take the other's in-flight runs for interrupted ones. The OS drops the lock when the
        holder dies, even by SIGKILL, so a killed campaign never blocks its resumption.
        """
        if self._lock_fd is not None:
            return
        try:
            import fcntl
        except ImportError:  # pragma: no cover - Windows: no advisory lock
            return
        fd = os.open(str(self.path) + ".lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            raise StudyStoreError(
                f"study store {self.path} is in use by another running campaign"
            ) from exc
        self._lock_fd = fd

    def release_lock(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # closing the descriptor releases the flock
            self._lock_fd = None

    # -- meta --------------------------------------------------------------------------------

    def get_meta(self, key: str, default: str | None = None) -> str | None:
        row = self._conn.execute("SELECT value FROM meta WHERE key=?", (key,)).fetchone()
        return row[0] if row else default

    def set_meta(self, key: str, value: str) -> None:
        with self.transaction() as c:
            c.execute(
                "INSERT INTO meta(key, value) VALUES (?, ?) "
                "ON CONFLICT(key) DO UPDATE SET value=excluded.value",
                (key, value),
            )

    # -- runs --------------------------------------------------------------------------------

    def add_design(self, stage: str, experiment: str, specs: Iterable[RunSpec]) -> list[str]:
        """Register design points (positions 0, 1, ...) and their runs; returns the run keys.

        Runs already in the store (same key) are reused, whatever their status. Existing
        design points at the same positions must refer to the same runs.
        """
        now = time.time()
        keys = []
        with self.transaction() as c:
            for pos, spec in enumerate(specs):
                key = spec.key
                keys.append(key)
                c.execute(
                    "INSERT OR IGNORE INTO runs(run_key, simulator, simulator_version, setup_json,"
                    " params_json, status, created) VALUES (?, ?, ?, ?, ?, 'pending', ?)",
                    (
                        key,
                        spec.simulator,
                        str(spec.simulator_version),
                        _dumps(dict(spec.setup)),
                        _dumps({k: float(v) for k, v in spec.params.items()}),
                        now,
                    ),
                )
                old = c.execute(
                    "SELECT run_key FROM design_points WHERE stage=? AND experiment=? "
                    "AND position=?",
                    (stage, experiment, pos),
                ).fetchone()
                if old is None:
                    c.execute(
                        "INSERT INTO design_points(stage, experiment, position, run_key) "
                        "VALUES (?, ?, ?, ?)",
                        (stage, experiment, pos, key),
                    )
                elif old[0] != key:
                    raise StudyStoreError(
                        f"design {stage}/{experiment} in {self.path} has a different run at "
                        f"position {pos}: the design changed (bounds, seed, setup or screening "
                        "result); delete the design with `--reset-stage` or use a new store"
                    )
        return keys

    def design_keys(self, stage: str, experiment: str) -> list[str]:
        """Run keys of a design, in position order."""
        rows = self._conn.execute(
            "SELECT run_key FROM design_points WHERE stage=? AND experiment=? ORDER BY position",
            (stage, experiment),
        ).fetchall()
        return [r[0] for r in rows]

    def stage_keys(self) -> list[tuple[str, str]]:
        """(stage, run key) of every design point; a run in two stages' designs appears twice."""
        rows = self._conn.execute("SELECT DISTINCT stage, run_key FROM design_points").fetchall()
        return [(r[0], r[1]) for r in rows]

    def delete_design(self, stage: str, experiment: str | None = None) -> None:
        """Forget a design's points (and the stage's results); the runs themselves are kept."""
        with self.transaction() as c:
            if experiment is None:
                c.execute("DELETE FROM design_points WHERE stage=?", (stage,))
            else:
                c.execute(
                    "DELETE FROM design_points WHERE stage=? AND experiment=?", (stage, experiment)
                )

    def get_runs(self, keys: Iterable[str]) -> list[dict]:
        """Rows of the given runs (dicts with decoded ``params``, ``setup``, ``responses``)."""
        out = []
        for key in keys:
            row = self._conn.execute("SELECT * FROM runs WHERE run_key=?", (key,)).fetchone()
            if row is None:
                raise KeyError(f"run {key} is not in the store")
            out.append(self._decode(row))
        return out

    def all_runs(self) -> list[dict]:
        rows = self._conn.execute("SELECT * FROM runs ORDER BY created, run_key").fetchall()
        return [self._decode(r) for r in rows]

    def wall_times(self) -> dict[tuple[str, str], list[float]]:
        """Wall times [s] of the finished runs, by :func:`cost_key` (simulator and setup):
        what a run of that kind costs on the machines that ran them."""
        out: dict[tuple[str, str], list[float]] = {}
        for r in self.all_runs():
            if r["status"] == "done" and r["wall_s"] is not None:
                out.setdefault(cost_key(r), []).append(float(r["wall_s"]))
        return out

    @staticmethod
    def _decode(row: sqlite3.Row) -> dict:
        d = dict(row)
        d["params"] = json.loads(d.pop("params_json"))
        d["setup"] = json.loads(d.pop("setup_json"))
        rj = d.pop("responses_json")
        d["responses"] = json.loads(rj) if rj else None
        return d

    def status_counts(self, keys: Iterable[str] | None = None) -> dict[str, int]:
        counts = dict.fromkeys(_STATUSES, 0)
        if keys is None:
            for status, n in self._conn.execute(
                "SELECT status, COUNT(*) FROM runs GROUP BY status"
            ):
                counts[status] = n
        else:
            for r in self.get_runs(keys):
                counts[r["status"]] += 1
        return counts

    def attempts(self, key: str) -> list[dict]:
        rows = self._conn.execute(
            "SELECT * FROM attempts WHERE run_key=? ORDER BY attempt", (key,)
        ).fetchall()
        return [dict(r) for r in rows]

    def reset_interrupted(self) -> int:
        """Runs left ``running`` by a dead campaign go back to ``pending``; returns how many.

        Call only while holding the campaign lock. Their open attempt is closed as
        ``interrupted`` and does not count against the retry budget.
        """
        now = time.time()
        with self.transaction() as c:
            keys = [r[0] for r in c.execute("SELECT run_key FROM runs WHERE status='running'")]
            for key in keys:
                c.execute(
                    "UPDATE attempts SET status='interrupted', finished=?, "
                    "error='campaign stopped while the run was in flight' "
                    "WHERE run_key=? AND status='running'",
                    (now, key),
                )
                c.execute(
                    "UPDATE runs SET status='pending', attempts=attempts-1 WHERE run_key=?",
                    (key,),
                )
        return len(keys)

    def mark_running(self, key: str) -> int:
        """Start a new attempt of a run; returns its attempt number (1-based)."""
        now = time.time()
        with self.transaction() as c:
            row = c.execute("SELECT attempts FROM runs WHERE run_key=?", (key,)).fetchone()
            attempt = int(row[0]) + 1
            n_logged = c.execute(
                "SELECT COALESCE(MAX(attempt), 0) FROM attempts WHERE run_key=?", (key,)
            ).fetchone()[0]
            c.execute(
                "UPDATE runs SET status='running', attempts=?, started=? WHERE run_key=?",
                (attempt, now, key),
            )
            # Interrupted attempts keep their rows, so the log numbering continues after them.
            c.execute(
                "INSERT INTO attempts(run_key, attempt, started, status) "
                "VALUES (?, ?, ?, 'running')",
                (key, int(n_logged) + 1, now),
            )
        return attempt

    def mark_done(
        self,
        key: str,
        responses: Mapping[str, float],
        *,
        wall_s: float,
        worker: str = "",
        code_version: str = "",
    ) -> None:
        now = time.time()
        with self.transaction() as c:
            c.execute(
                "UPDATE runs SET status='done', responses_json=?, error=NULL, finished=?, "
                "wall_s=?, worker=?, code_version=? WHERE run_key=?",
                (_dumps(dict(responses)), now, wall_s, worker, code_version, key),
            )
            c.execute(
                "UPDATE attempts SET status='done', finished=?, worker=? "
                "WHERE run_key=? AND status='running'",
                (now, worker, key),
            )

    def mark_failed(
        self, key: str, error: str, *, wall_s: float | None = None, worker: str = ""
    ) -> None:
        now = time.time()
        with self.transaction() as c:
            c.execute(
                "UPDATE runs SET status='failed', error=?, finished=?, wall_s=?, worker=? "
                "WHERE run_key=?",
                (error, now, wall_s, worker, key),
            )
            c.execute(
                "UPDATE attempts SET status='failed', finished=?, error=?, worker=? "
                "WHERE run_key=? AND status='running'",
                (now, error, worker, key),
            )

    def mark_pending(self, key: str) -> None:
        """Put a run that was handed out but never started back to ``pending``."""
        with self.transaction() as c:
            c.execute(
                "UPDATE attempts SET status='interrupted', finished=?, "
                "error='campaign stopped before the run finished' "
                "WHERE run_key=? AND status='running'",
                (time.time(), key),
            )
            c.execute(
                "UPDATE runs SET status='pending', attempts=MAX(attempts-1, 0) WHERE run_key=?",
                (key,),
            )

    # -- stage results -------------------------------------------------------------------------

    def put_result(self, stage: str, experiment: str, payload) -> None:
        with self.transaction() as c:
            c.execute(
                "INSERT INTO results(stage, experiment, payload_json, updated) VALUES (?, ?, ?, ?)"
                " ON CONFLICT(stage, experiment) DO UPDATE SET payload_json=excluded.payload_json,"
                " updated=excluded.updated",
                (stage, experiment, _dumps(payload), time.time()),
            )

    def get_result(self, stage: str, experiment: str = ""):
        row = self._conn.execute(
            "SELECT payload_json FROM results WHERE stage=? AND experiment=?", (stage, experiment)
        ).fetchone()
        return json.loads(row[0]) if row else None

    def delete_results(self, stage: str) -> None:
        with self.transaction() as c:
            c.execute("DELETE FROM results WHERE stage=?", (stage,))


def worker_label() -> str:
    """``host:pid`` of the calling process."""
    return f"{socket.gethostname()}:{os.getpid()}"

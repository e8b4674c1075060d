"""Executing the runs of a study store: local processes, a Dask cluster, or in-process.

:func:`run_campaign` takes run keys already registered in a :class:`StudyStore` and brings each
to ``done`` (or ``failed`` after its retries):

* runs already ``done`` are skipped, so a campaign can be repeated or resumed at no cost;
* runs left ``running`` by a killed campaign are reset to ``pending`` and run again (their result
  never reached the store, so nothing is repeated that was recorded);
* every start, success and failure is a separate committed transaction;
* a failed run (an exception in the simulator, a non-finite or missing response, a crashed worker
  process) is recorded with its error text and resubmitted until it has had ``1 + retries``
  attempts; after that it stays ``failed`` (visible in the store and the report) until a campaign
  with ``retry_failed=True`` grants it a fresh budget;
* a failure the simulator marks as its outcome (an exception with ``retryable = False``: a
  response the run does not reach, which every attempt reproduces) is not retried: its error
  text starts with :data:`NOT_RETRIED`, and a resumed campaign leaves it failed too (unless
  ``retry_failed``);
* a worker process that dies breaks the pool and every run in flight with it: when several were
  in flight none is charged (the culprit is unknown); they run again one at a time, where a
  crash is the run's own and is charged;
* worker processes end with the campaign, also when it is killed with SIGKILL
  (:func:`flexparcel.io.lifetime.die_with_parent`);
* SIGUSR1 (POSIX) drains the campaign: it starts no new run, lets the runs in flight finish
  and record their results, then raises :class:`CampaignDrained` with the rest still
  ``pending``. A stop that loses nothing, where Ctrl-C (SIGINT) or a kill puts the runs in
  flight back to ``pending`` and the next campaign runs them from their start (a run at the
  paper's mesh can take the better part of an hour);
* a ``deadline`` drains it the same way before the first run that would end after it: a
  run's cost is the median wall time of the store's finished runs of its simulator and setup
  (:func:`~flexparcel.calibration.store.cost_key`), updated as runs finish, else its stated
  cost (``stated_costs``: a study's ``estimated_run_s``); a run of a kind with neither
  starts (a job with a wall-time limit on a cluster, a machine lent for some hours);
* a simulator marked ``resumable`` (an attribute of its function, e.g. the finite-element
  tests of :mod:`flexparcel.scenarios.simulators`) gets a checkpoint path per run,
  ``run_checkpoint``, in the folder ``STORE.runs`` beside the store: a run interrupted by
  a kill or a crash resumes from its last save in the next campaign instead of starting
  over. The file goes once the run is done or has failed for good. (Such a checkpoint holds
  the run's frames so far: tens of MB at the paper's mesh; not for version control.)

Executors: ``concurrent.futures.ProcessPoolExecutor`` (``workers`` processes, the default),
``dask.distributed`` (``scheduler`` = the address of a running scheduler; workers need flexparcel
and the simulator's module installed), or in-process serial execution (``workers=0``, for
debugging and small tests). At most as many runs are in flight as there are workers, so a run
handed to an executor is a run that is actually executing; that is what makes ``running`` in the
store mean "in flight".
"""

from __future__ import annotations

import os
import signal
import statistics
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from flexparcel.calibration.simulators import get_simulator
from flexparcel.calibration.store import StudyStore, cost_key, worker_label
from flexparcel.io.lifetime import die_with_parent

__all__ = ["CampaignDrained", "CampaignReport", "execute_run", "not_retried", "run_campaign"]

_MAX_ERROR_CHARS = 8000

NOT_RETRIED = "not retried (the simulator's outcome, the same on every attempt): "
"""Start of the stored error of a failed run that is not retried."""


def not_retried(error: str | None) -> bool:
    """Whether a run's stored ``error`` is the simulator's outcome (a response not reached),
    recorded once and not retried."""
    return bool(error) and str(error).startswith(NOT_RETRIED)


@dataclass
class CampaignReport:
    """What a campaign did. ``failed`` lists the run keys still failed at its end."""

    requested: int = 0
    already_done: int = 0
    interrupted_reset: int = 0
    attempts: int = 0
    succeeded: int = 0
    failed: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    executor: str = ""

    @property
    def complete(self) -> bool:
        return not self.failed


class CampaignDrained(Exception):
    """A campaign stopped by SIGUSR1 or its deadline once its runs in flight had finished;
    ``pending`` runs are left for the next campaign (the same command goes on with them)."""

    def __init__(self, pending: int, finished: int, reason: str = "on SIGUSR1") -> None:
        self.pending = pending
        self.finished = finished
        self.reason = reason
        super().__init__(
            f"drained {reason}: the {finished} run(s) in flight finished and were recorded, "
            f"{pending} left pending; the same command goes on with them"
        )


class _Drain:
    """SIGUSR1 sets :attr:`requested` between :meth:`start` and :meth:`stop` (main thread,
    POSIX only; the previous handler comes back); :attr:`finished` counts the runs that
    ended after it."""

    def __init__(self) -> None:
        self.requested = False
        self.reason = "on SIGUSR1"
        self.finished = 0
        self._previous = None
        main = threading.current_thread() is threading.main_thread()
        self._on = main and hasattr(signal, "SIGUSR1")

    def start(self) -> None:
        if self._on:
            self._previous = signal.signal(signal.SIGUSR1, self._handle)

    def _handle(self, signum, frame) -> None:
        self.request("SIGUSR1", "on SIGUSR1")

    def request(self, why: str, reason: str) -> None:
        if not self.requested:
            print(f"calibrate: {why}: starting no new run; the runs in flight finish first",
                  file=sys.stderr, flush=True)  # fmt: skip
            self.reason = reason
        self.requested = True

    def stop(self) -> None:
        if self._on:
            signal.signal(signal.SIGUSR1, self._previous)


def _init_worker(threads: int) -> None:
    # a campaign killed with SIGKILL takes its workers along (no run goes on unobserved)
    die_with_parent()
    # the drain signal is the controller's: a worker that got it (a signal sent to the whole
    # process group) would otherwise die of it and take its run along
    if hasattr(signal, "SIGUSR1"):
        signal.signal(signal.SIGUSR1, signal.SIG_IGN)
    # Two BLAS/OpenMP pools on few cores slow each other down; a worker is one run, one thread.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ.setdefault(var, str(threads))


def execute_run(
    simulator: str,
    version: str,
    setup: Mapping,
    params: Mapping[str, float],
    expect: Sequence[str] = (),
    modules: Sequence[str] = (),
    threads: int | None = None,
    checkpoint: str | None = None,
) -> dict:
    """Run one simulation; executed in a worker. Never raises for simulator errors.
    ``checkpoint``: the run's checkpoint path, given to a ``resumable`` simulator.

    Returns ``{"ok": True, "responses": {...}, ...}`` or ``{"ok": False, "error": text, ...}``,
    with ``wall_s`` [s], ``worker`` (``host:pid``) and ``code_version``.
    """
    from flexparcel._version import __version__

    t0 = time.perf_counter()
    out: dict = {"worker": worker_label()}
    try:
        info = get_simulator(simulator, modules)
        out["code_version"] = f"flexparcel {__version__}; {simulator} {info.version}"
        if str(info.version) != str(version):
            raise RuntimeError(
                f"simulator {simulator!r} here is version {info.version}, the study store "
                f"expects version {version} (a worker with a different installation?)"
            )
        limiter = None
        if threads:
            try:
                from threadpoolctl import threadpool_limits

                limiter = threadpool_limits(threads)
            except ImportError:  # pragma: no cover - threadpoolctl ships with scikit-learn
                limiter = None
        extra = {}
        if checkpoint is not None and getattr(info.func, "resumable", False):
            extra["run_checkpoint"] = checkpoint
        try:
            raw = info.func(dict(params), **extra, **dict(setup))
        finally:
            if limiter is not None:
                limiter.restore_original_limits()
        if not isinstance(raw, Mapping):
            raise TypeError(
                f"simulator {simulator!r} returned {type(raw).__name__}, expected a mapping "
                "of response names to numbers"
            )
        responses = {}
        for name, value in raw.items():
            v = float(value)
            if v != v or v in (float("inf"), float("-inf")):
                # Never write NaNs as results: a non-finite response is a failed run.
                raise ValueError(f"simulator {simulator!r} returned non-finite {name} = {v}")
            responses[str(name)] = v
        missing = [r for r in expect if r not in responses]
        if missing:
            raise KeyError(
                f"simulator {simulator!r} returned no response {', '.join(map(repr, missing))} "
                f"(it returned: {', '.join(responses) or 'nothing'})"
            )
        out.update(ok=True, responses=responses)
    except Exception as exc:
        error = traceback.format_exc()[-_MAX_ERROR_CHARS:]
        if getattr(exc, "retryable", True) is False:
            error = NOT_RETRIED + f"{type(exc).__name__}: {exc}\n{error}"
        out.update(ok=False, error=error)
    out["wall_s"] = time.perf_counter() - t0
    out.setdefault("code_version", f"flexparcel {__version__}")
    return out


class _SerialExecutor:
    """Runs each task at submit time in this process (``workers=0``)."""

    def submit(self, fn, *args, **kwargs):
        from concurrent.futures import Future

        fut: Future = Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # pragma: no cover - execute_run catches Exception
            fut.set_exception(exc)
        return fut

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        pass


def _make_executor(workers: int | None, scheduler, start_method: str, threads: int):
    """(executor, max_in_flight, label, closer)."""
    if scheduler is not None:
        from distributed import Client

        client = scheduler if isinstance(scheduler, Client) else Client(scheduler, timeout="30s")
        executor = client.get_executor(pure=False)
        n = max(1, sum(client.nthreads().values()))
        own = client is not scheduler

        def close():
            executor.shutdown(wait=False)
            if own:
                client.close()

        return executor, n, f"dask {client.scheduler.address}", close
    if workers == 0:
        ex = _SerialExecutor()
        return ex, 1, "serial", lambda: None
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    n = workers if workers is not None else (os.cpu_count() or 1)
    ex = ProcessPoolExecutor(
        max_workers=n,
        mp_context=multiprocessing.get_context(start_method),
        initializer=_init_worker,
        initargs=(threads,),
    )

    def close():
        ex.shutdown(wait=True, cancel_futures=True)

    return ex, n, f"{n} local process(es)", close


def run_campaign(
    store: StudyStore,
    keys: Iterable[str],
    *,
    workers: int | None = None,
    scheduler=None,
    retries: int = 2,
    retry_failed: bool = False,
    expect: Mapping[str, Sequence[str]] | None = None,
    modules: Sequence[str] = (),
    threads: int = 1,
    start_method: str = "spawn",
    progress: bool = True,
    desc: str = "runs",
    deadline: float | None = None,
    stated_costs: Mapping[tuple[str, str], float] | None = None,
) -> CampaignReport:
    """Execute the runs ``keys`` of ``store`` that are not done yet.

    Parameters
    ----------
    workers:
        Local worker processes (default: all CPUs); ``0`` runs serially in this process.
    scheduler:
        Address of a Dask scheduler (``"tcp://host:8786"``) or a ``distributed.Client``; when
        given, runs go to that cluster instead of local processes.
    retries:
        Extra attempts after a failure (a run gets at most ``1 + retries`` attempts).
    retry_failed:
        Give runs that exhausted their attempts in earlier campaigns a fresh budget.
    expect:
        ``{run key: response names}`` the run must return, else it fails.
    modules:
        Modules to import (in workers too) so that the simulators register themselves.
    threads:
        BLAS/OpenMP threads per worker process.
    deadline:
        ``time.time()`` [s] by which the runs started must have ended (see the module
        docstring); None: no limit.
    stated_costs:
        Cost [s] of a kind of run (:func:`~flexparcel.calibration.store.cost_key`) that has
        no finished run in the store yet (a study's ``estimated_run_s``).
    """
    if retries < 0:
        raise ValueError(f"retries must be >= 0, got {retries}")
    t_start = time.perf_counter()
    keys = list(dict.fromkeys(keys))  # unique, order kept
    report = CampaignReport(requested=len(keys))
    expect = expect or {}
    store.acquire_lock()
    try:
        report.interrupted_reset = store.reset_interrupted()
        rows = {r["run_key"]: r for r in store.get_runs(keys)}
        budget: dict[str, int] = {}
        queue: deque[str] = deque()
        for key in keys:
            r = rows[key]
            if r["status"] == "done":
                report.already_done += 1
                continue
            spent = r["attempts"] >= 1 + retries or not_retried(r.get("error"))
            if r["status"] == "failed" and not retry_failed and spent:
                report.failed.append(key)
                continue
            fresh = r["status"] == "failed" and retry_failed
            budget[key] = (r["attempts"] if fresh else 0) + 1 + retries
            queue.append(key)
        if not queue:
            report.wall_s = time.perf_counter() - t_start
            return report

        executor, max_in_flight, label, close = _make_executor(
            workers, scheduler, start_method, threads
        )
        report.executor = label
        bar = _progress(progress, total=len(keys), initial=report.already_done, desc=desc)
        in_flight: dict = {}
        suspects: set[str] = set()  # runs in flight when a worker died
        crashed_with: set[str] = set()
        pool_broken = False
        # Worker processes get their BLAS pools limited; in-process runs keep the caller's.
        run_threads = None if label == "serial" else threads
        drain = _Drain()
        walls = store.wall_times() if deadline is not None else {}
        stated = dict(stated_costs or {})
        try:
            drain.start()
            while (queue and not drain.requested) or in_flight:
                if pool_broken and not in_flight:
                    # A crashed worker process breaks the whole pool: every run in flight got
                    # the error (and an attempt); a fresh pool runs the rest.
                    close()
                    executor, max_in_flight, label, close = _make_executor(
                        workers, scheduler, start_method, threads
                    )
                    pool_broken = False
                # while runs are under suspicion of having crashed a worker, one at a time
                limit = 1 if suspects else max_in_flight
                while not drain.requested and not pool_broken and queue and len(in_flight) < limit:
                    key = _next_run(queue, suspects)
                    kind = cost_key(rows[key])
                    cost = walls.get(kind) or ([stated[kind]] if kind in stated else None)
                    late = _ends_after(deadline, cost)
                    if late:
                        queue.appendleft(key)
                        drain.request(late, "at the time limit")
                        break
                    store.mark_running(key)
                    r = rows[key]
                    try:
                        fut = executor.submit(
                            execute_run,
                            r["simulator"],
                            r["simulator_version"],
                            r["setup"],
                            r["params"],
                            tuple(expect.get(key, ())),
                            tuple(modules),
                            run_threads,
                            str(_checkpoint_path(store, key)),
                        )
                    except Exception:  # the pool broke between two submissions
                        store.mark_pending(key)
                        queue.appendleft(key)
                        pool_broken = True
                        break
                    report.attempts += 1
                    in_flight[fut] = key
                if not in_flight:
                    continue
                for fut in _wait_any(list(in_flight)):
                    outcome = _outcome(fut)
                    broken = outcome.pop("broken", False)
                    if broken and not pool_broken:  # the runs in flight when the pool broke
                        crashed_with = set(in_flight.values())
                    pool_broken |= broken
                    key = in_flight.pop(fut)
                    drain.finished += drain.requested
                    if broken and len(crashed_with) > 1:
                        # a worker died while several runs were in flight: which one killed
                        # it is unknown, so none is charged; each runs again alone, where a
                        # crash is its own
                        store.mark_pending(key)
                        report.attempts -= 1
                        suspects.add(key)
                        queue.appendleft(key)
                        continue
                    suspects.discard(key)
                    if outcome["ok"]:
                        _checkpoint_path(store, key).unlink(missing_ok=True)
                        walls.setdefault(cost_key(rows[key]), []).append(outcome["wall_s"])
                        store.mark_done(
                            key,
                            outcome["responses"],
                            wall_s=outcome["wall_s"],
                            worker=outcome.get("worker", ""),
                            code_version=outcome.get("code_version", ""),
                        )
                        report.succeeded += 1
                        if bar is not None:
                            bar.update(1)
                        continue
                    store.mark_failed(
                        key,
                        outcome["error"],
                        wall_s=outcome.get("wall_s"),
                        worker=outcome.get("worker", ""),
                    )
                    # a failed attempt starts its retry over (its checkpoint may be the cause)
                    _checkpoint_path(store, key).unlink(missing_ok=True)
                    again = store.get_runs([key])[0]["attempts"] < budget[key]
                    if again and not not_retried(outcome["error"]):
                        queue.append(key)
                    else:
                        report.failed.append(key)
                        if bar is not None:
                            bar.update(1)
        finally:
            drain.stop()
            for key in in_flight.values():
                # Interrupted (KeyboardInterrupt, error in this process): not the run's fault.
                store.mark_pending(key)
            if bar is not None:
                bar.close()
            close()
    finally:
        store.release_lock()
    report.wall_s = time.perf_counter() - t_start
    if drain.requested and queue:
        raise CampaignDrained(len(queue), drain.finished, drain.reason)
    return report


def _checkpoint_path(store: StudyStore, key: str):
    """Where run ``key`` of ``store`` keeps its checkpoint: ``STORE.runs/KEY.npz``."""
    return store.path.with_name(store.path.name + ".runs") / f"{key[:32]}.npz"


def _ends_after(deadline: float | None, walls: list[float] | None) -> str:
    """Why a run of measured wall times ``walls`` [s] started now would end after
    ``deadline``, or "" (no deadline, no measured cost, or it fits)."""
    if deadline is None or not walls:
        return ""
    cost = statistics.median(walls)
    left = deadline - time.time()
    if cost <= left:
        return ""
    return f"time limit: the next run takes about {cost:.0f} s, {max(left, 0.0):.0f} s are left"


def _next_run(queue: deque, suspects: set) -> str:
    """The next run to start: a suspect first (see run_campaign), else the queue's head."""
    for i, key in enumerate(queue):
        if key in suspects:
            del queue[i]
            return key
    return queue.popleft()


def _wait_any(futures: list):
    from concurrent.futures import FIRST_COMPLETED, wait

    done, _ = wait(futures, return_when=FIRST_COMPLETED)
    return done


def _outcome(fut) -> dict:
    from concurrent.futures.process import BrokenProcessPool

    try:
        return dict(fut.result())
    except BrokenProcessPool as exc:
        return {
            "ok": False,
            "broken": True,
            "error": f"worker process died while this run was in flight: {exc!r}",
        }
    except Exception as exc:  # e.g. a Dask worker lost (KilledWorker), a transport error
        return {
            "ok": False,
            "error": "".join(traceback.format_exception(exc))[-_MAX_ERROR_CHARS:],
        }


def _progress(enabled: bool, **kwargs):
    if not enabled:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover
        return None
    return tqdm(unit="run", leave=False, **kwargs)

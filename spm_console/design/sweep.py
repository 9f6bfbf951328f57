"""Run a design sweep on Dask (``dask.distributed``): an embedded local cluster on the
allowed cores, or an existing cluster's scheduler.

Each design is one task (:func:`spm_console.design.evaluate.evaluate`) with a key made of
the spec's digest and the design's index; the driver writes each row to the folder's
journal as it finishes (:mod:`spm_console.design.table`), so a stopped sweep resumes where
it stopped. Workers hold no state between designs: when a worker dies, the scheduler runs
its tasks again elsewhere; a design that kills its worker repeatedly (the scheduler's
``allowed-failures``) is a row with that reason. Ctrl-C (or SIGTERM / SIGHUP / SIGQUIT, to
this process or its whole group) stops the sweep: the cluster is closed, the table is written
from what is done, and the same command resumes.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import resource
import signal
import time
from collections.abc import Callable, Generator, Iterator
from concurrent.futures import CancelledError
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from spm_console.design.evaluate import INTERNAL_ERROR, KILLED_WORKER, DesignRow, DesignTask, evaluate
from spm_console.design.scheduler_probe import probe_scheduler
from spm_console.design.spec import SweepSpec
from spm_console.design.table import Journal, SweepInfo, create_folder, read_done, write_table
from spm_console.errors import BadInputError, ClusterLostError, InterruptedBySignalError

#: The workers' environment, over Dask's: glibc's own heap trimming. Dask's 64 kB threshold
#: made a design's build (large temporary arrays) twice as slow in a worker: 2.2 s against
#: 1.1 s in this process (docs/decisions/design-sweeps.md). BLAS stays on one thread.
WORKER_ENVIRON: dict[str, str | None] = {"MALLOC_TRIM_THRESHOLD_": None}

#: Designs sent ahead per worker (and at least IN_FLIGHT_MIN): the rest wait in this process.
IN_FLIGHT_PER_WORKER = 4
IN_FLIGHT_MIN = 16

#: How long to wait for an existing scheduler to answer, s.
CONNECT_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class SweepProgress:
    """Where a sweep stands."""

    done: int
    """Designs done, this run and earlier ones."""
    total: int
    computed: int
    """Designs computed in this run."""
    elapsed_s: float
    """Since this run's first task was sent (its cluster up and warm), s."""

    @property
    def rate_per_s(self) -> float:
        return self.computed / self.elapsed_s if self.elapsed_s > 0 else 0.0

    @property
    def eta_s(self) -> float | None:
        r = self.rate_per_s
        return (self.total - self.done) / r if r > 0 else None


@dataclass(frozen=True)
class SweepOutcome:
    """A finished sweep."""

    folder: Path
    table: Path
    total: int
    resumed: int
    """Designs found done in the folder before this run."""
    computed: int
    failed: int
    """Designs that could not be built (rows with a reason)."""
    internal_errors: int
    """Of those, the designs that met a bug (run again when the sweep is resumed)."""
    seconds: float
    workers: int
    worker_peak_rss_mb: dict[str, float] = field(default_factory=dict)
    """Peak resident memory of each worker process, MB (embedded cluster or not)."""


def allowed_cores() -> int:
    """The CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


#: The terminal's keys that signal the whole foreground process group (Ctrl-C, Ctrl-\\).
TERMINAL_SIGNALS = {signal.SIGINT, signal.SIGQUIT}
#: Signals to a whole process group that would kill multiprocessing's resource tracker (it
#: ignores SIGINT and SIGTERM itself): closing the terminal, Ctrl-\\, ``kill -HUP -- -PGID``.
TRACKER_SHIELDED = {signal.SIGHUP, signal.SIGQUIT}


def _start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (one process, shared by this one's children:
    the workers' semaphores are registered with it) with :data:`TRACKER_SHIELDED` blocked,
    which it inherits and never unblocks, so that a signal to the whole group leaves it alive.
    Killed, it was started again on the next use knowing none of the names registered before,
    and printed a ``KeyError`` traceback for each one unregistered later. The standard library
    blocks SIGINT and SIGTERM around the start and then unblocks them rather than restoring
    the calling thread's mask: the mask is restored here."""
    from multiprocessing import resource_tracker

    before = signal.pthread_sigmask(signal.SIG_BLOCK, TRACKER_SHIELDED)
    try:
        resource_tracker.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


@contextlib.contextmanager
def _terminal_signals_held() -> Iterator[None]:
    """Ctrl-C and Ctrl-\\ held (blocked, not lost) while the local cluster starts. Its
    threads are made now and keep them blocked, and so does every worker process they start,
    now or when a worker is restarted: the terminal's keys reach only this process, which
    closes the cluster in order. A key pressed meanwhile is delivered when the block ends."""
    _start_resource_tracker()  # first: it keeps the signals its start blocks
    before = signal.pthread_sigmask(signal.SIG_BLOCK, TERMINAL_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


@contextlib.contextmanager
def _dask_logs_quiet() -> Iterator[None]:
    """Dask's own log lines off in this process while it serves a sweep: what goes wrong is
    the sweep's to say (a row's reason, a lost cluster's message), not a traceback of Dask's
    reconnection attempts. Entered after ``distributed`` is imported (it sets its loggers'
    levels then)."""
    names = ["distributed", *(n for n in logging.root.manager.loggerDict
                              if n.startswith("distributed."))]
    before = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for n, level in before.items():
            logging.getLogger(n).setLevel(level)


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A client of ``scheduler`` (``tcp://host:port``), or of an embedded local cluster of
    ``workers`` single-threaded processes (default: one per allowed core)."""
    if scheduler is not None:
        from distributed import Client

        with _dask_logs_quiet():
            yield from _existing(Client, scheduler)
        return
    n = workers or allowed_cores()
    with contextlib.ExitStack() as stack:
        with _terminal_signals_held():
            # imported here: the threads distributed starts (its IO loop is made on import)
            # hold the signals too, and so do the workers they start
            import dask
            from distributed import Client, LocalCluster

            stack.enter_context(_dask_logs_quiet())
            environ = {**dask.config.get("distributed.nanny.pre-spawn-environ"), **WORKER_ENVIRON}
            with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                       silence_logs=logging.CRITICAL,
                                       preload=["spm_console.design.worker_setup"])
            stack.callback(cluster.close)  # closed even when a held Ctrl-C lands next
            client = Client(cluster, set_as_default=False)
            stack.callback(client.close)
        yield client


def _existing(Client: Any, scheduler: str) -> Iterator[Any]:
    """A client of an existing scheduler (BadInputError when none answers, or another service
    does: asked first, by hand, :func:`probe_scheduler`)."""
    probe_scheduler(scheduler)
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError, MemoryError) as exc:
        raise BadInputError(f"--scheduler {scheduler}: no Dask scheduler answered "
                            f"({exc})") from None
    try:
        yield client
    finally:
        client.close()


def _killed_row(task: DesignTask, exc: BaseException) -> DesignRow:
    return DesignRow(task.index, dict(task.params), False,
                     f"{KILLED_WORKER} the worker running it each time it ran ({exc}); a "
                     "resumed sweep runs it again", None)


def _imports(pairs: bool) -> int:
    """Run on each worker before the first design: the modules a design needs."""
    import importlib

    importlib.import_module("spm_console.design.evaluate")
    if pairs:
        importlib.import_module("spm_console.core.planning.mintime")
    return os.getpid()


def _warm_up(client: Any, pairs: bool) -> None:
    """Wait for a worker, and have every worker import what a design needs (a cluster whose
    workers cannot import this package is refused before any design is sent)."""
    try:
        client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
    except TimeoutError:
        raise BadInputError(f"the Dask scheduler has no worker after {CONNECT_TIMEOUT_S:g} s: "
                            "start some (dask worker ADDRESS)") from None
    try:
        client.run(_imports, pairs)
    except ImportError as exc:
        raise BadInputError(f"the Dask workers cannot import what a design needs ({exc}): install "
                            "this project in the workers' environment") from None


def _results(tasks: list[DesignTask], digest: str, scheduler: str | None, workers: int | None,
             on_client: Callable[[Any], None] | None, ready: Callable[[], None],
             peak: dict[str, float]) -> Generator[DesignRow, None, None]:
    """The tasks' rows as they finish: in this process with ``workers == 0`` (no Dask), else
    on the cluster; ``ready()`` once they can run (the cluster is up); ``peak`` receives the
    workers' peak memory at the end."""
    if workers == 0 and scheduler is None:
        ready()
        for task in tasks:
            yield evaluate(task)
        peak["local"] = _peak_rss_mb()
        return
    with dask_client(scheduler, workers) as client:
        _warm_up(client, bool(tasks[0].pairs))
        ready()
        if on_client is not None:
            on_client(client)
        yield from _on_cluster(client, tasks, digest)
        with contextlib.suppress(Exception):  # a report, never a reason to fail
            peak.update({str(k): float(v) for k, v in client.run(_peak_rss_mb).items()})


def _on_cluster(client: Any, tasks: list[DesignTask], digest: str) -> Iterator[DesignRow]:
    """The tasks' rows from the cluster as they finish, with at most :data:`IN_FLIGHT_PER_WORKER`
    per worker sent ahead (the scheduler holds a window, not the whole sweep). ClusterLostError
    when the cluster goes away (the rows so far are kept)."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    window = max(IN_FLIGHT_MIN, IN_FLIGHT_PER_WORKER * max(1, len(
        client.scheduler_info().get("workers", {}))))
    pending = iter(tasks)

    def send(n: int) -> list[Any]:
        batch = list(itertools.islice(pending, n))
        return client.map(evaluate, batch, key=[f"design-{digest[:16]}-{t.index}" for t in batch],
                          pure=False) if batch else []

    by_key = {t_key: t for t_key, t in ((f"design-{digest[:16]}-{t.index}", t) for t in tasks)}
    try:
        done = as_completed(send(window), loop=client.loop)
        for fut in done:
            exc = fut.exception() if fut.status == "error" else None
            if isinstance(exc, KilledWorker):
                row = _killed_row(by_key[fut.key], exc)
            elif exc is not None:  # evaluate() returns a row for every design: the cluster's
                raise ClusterLostError(f"the Dask cluster failed a design's task ({exc!r})")
            else:
                row = fut.result()
            fut.release()
            for nxt in send(1):
                done.add(nxt)
            yield row
    except (CancelledError, OSError, TimeoutError) as exc:
        raise ClusterLostError(f"the Dask cluster was lost ({type(exc).__name__}: {exc})") \
            from None


def run_sweep(spec: SweepSpec, folder: Path, scheduler: str | None = None,
              workers: int | None = None,
              progress: Callable[[SweepProgress], None] | None = None,
              on_client: Callable[[Any], None] | None = None) -> SweepOutcome:
    """Run (or resume) ``spec`` into ``folder`` on ``scheduler``, or on a local cluster of
    ``workers`` processes (None: one per allowed core; 0: in this process, without Dask);
    ``progress`` after each design, ``on_client(client)`` once a cluster is up.
    InterruptedBySignalError on Ctrl-C / SIGTERM / SIGHUP, after the table is written from
    what is done."""
    t0 = time.perf_counter()
    rows = read_done(folder, spec)
    info = SweepInfo.of(spec)
    resumed = len(rows)
    step = spec.base.workspace.step_deg
    pairs = tuple((tuple(p.start_deg), tuple(p.goal_deg)) for p in spec.pairs)
    tasks = [DesignTask(i, spec.params(i), spec.base_text, step, pairs)  # type: ignore[arg-type]
             for i in range(spec.count) if i not in rows]
    computed = 0
    peak: dict[str, float] = {}
    journals: list[Journal] = []

    t_send = [time.perf_counter()]

    def ready() -> None:  # the folder is made only once the designs can run
        create_folder(folder, spec)
        journals.append(Journal(folder))
        t_send[0] = time.perf_counter()  # rates count from here: the cluster is up and warm

    if not tasks:
        ready()
    results = _results(tasks, spec.digest, scheduler, workers, on_client, ready, peak)
    try:
        for row in results if tasks else ():
            journals[0].append(row)
            rows[row.index] = row
            computed += 1
            if progress is not None:
                progress(SweepProgress(len(rows), spec.count, computed,
                                       time.perf_counter() - t_send[0]))
    except (KeyboardInterrupt, ClusterLostError) as exc:
        results.close()  # the cluster closes now, before the message
        if journals:
            write_table(folder, info, rows)
        kept = (f"{len(rows)} of {spec.count} designs done, kept in {folder}; the same command "
                "resumes it") if journals else "nothing was computed"
        if isinstance(exc, ClusterLostError):
            raise ClusterLostError(f"{exc.message}: {kept}") from None
        why = f" by {exc.args[0]}" if exc.args else ""
        raise InterruptedBySignalError(f"sweep stopped{why}: {kept}") from None
    finally:
        results.close()
        for j in journals:
            j.close()
    table = write_table(folder, info, rows)
    return SweepOutcome(folder=folder, table=table, total=spec.count, resumed=resumed,
                        computed=computed, failed=sum(1 for r in rows.values() if not r.ok),
                        internal_errors=sum(1 for r in rows.values()
                                            if r.reason.startswith(INTERNAL_ERROR)),
                        seconds=time.perf_counter() - t0, workers=len(peak),
                        worker_peak_rss_mb=peak)

"""Background work in worker processes: bounded in time, cancellable, killable, shared fairly.

A bifurcation diagram or a 2-D map runs seconds to minutes of compiled code. In a thread it
could only be asked to stop between chunks, and a job stuck inside the solver would hold its
worker for ever, and every other session's work behind it. Here each job runs in one of a
few worker processes (``spawn``: a clean interpreter that loads the compiled kernels from
numba's disk cache):

* **one queue**, first come first served; a session has at most one job of each kind: a new
  request replaces its queued job and cancels its running one;
* **cancel** sets the job's flag, which the work polls between chunks (:func:`cancelled`);
  a job still running ``grace`` seconds later is killed with its process;
* **time limit**: a job running longer than its limit is killed the same way and reports an
  error; the process is replaced at once, so the pool never shrinks. A new process takes jobs
  only once it has warmed up (imports, compiled kernels), so its start, slow on a loaded
  machine, never counts against a job's limit; one that cannot warm up within
  :data:`WARM_LIMIT` is replaced;
* **session end**: :meth:`JobPool.cancel_session` cancels all of a session's jobs.

Callbacks (``on_progress(fraction)``, ``on_done(result)``, ``on_error(message)``) run on the
pool's reader threads and never after a cancel; the session moves them onto its own
document. This module imports nothing heavy, since every worker process imports it first.
"""
from __future__ import annotations

import atexit
import collections
import itertools
import logging
import multiprocessing as mp
import multiprocessing.util  # noqa: F401  (its exit handler first, so ours runs before it)
import signal
import threading
import time
import weakref
from typing import Any, Callable

log = logging.getLogger(__name__)

_CTX = mp.get_context("spawn")
#: Seconds a new worker process may take to warm up before it is replaced.
WARM_LIMIT = 300.0
#: The job running in this process, when it is a worker: its connection, id and cancel flag.
_CURRENT: dict[str, Any] = {}


def report(done: int, total: int) -> None:
    """Progress of the job running in this worker (a no-op outside a worker); at most 10 per s."""
    conn = _CURRENT.get("conn")
    if conn is None:
        return
    now = time.monotonic()
    if done < total and now - _CURRENT.get("sent", 0.0) < 0.1:
        return
    _CURRENT["sent"] = now
    try:
        conn.send(("progress", _CURRENT["job"], done / max(total, 1)))
    except (OSError, ValueError):
        pass


def cancelled() -> bool:
    """Whether the job running in this worker was cancelled (False outside a worker)."""
    flag = _CURRENT.get("flag")
    return bool(flag is not None and flag.is_set())


def _worker_main(conn, flag, warm: Callable[[], Any] | None) -> None:
    """The loop of one worker process: receive a job, run it, send its outcome."""
    if warm is not None:
        try:
            warm()
        except Exception:  # a failed warm-up only costs the first job its compile time
            pass
    try:
        conn.send(("ready", 0, None))
    except (OSError, ValueError):
        return
    _CURRENT.update(conn=conn, flag=flag)
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        job_id, fn, args, kwargs = msg
        _CURRENT.update(job=job_id, sent=0.0)
        try:
            out = ("done", job_id, fn(*args, **kwargs))
        except BaseException as exc:  # reported to its own session only
            text = " ".join(str(exc).split())[:500]
            out = ("error", job_id, f"{type(exc).__name__}: {text}" if text else type(exc).__name__)
        try:
            conn.send(out)
        except Exception as exc:  # an unpicklable result is an error of that job
            conn.send(("error", job_id, f"the result could not be sent back: {exc}"))


class Job:
    """One request: queued, then running in a worker, then done, failed or cancelled."""

    def __init__(self, owner: tuple, fn: Callable, args: tuple, kwargs: dict, time_limit: float,
                 on_progress, on_done, on_error, pool: "JobPool"):
        self.id = next(JobPool._ids)
        self.owner, self.fn, self.args, self.kwargs = owner, fn, args, kwargs
        self.time_limit = time_limit
        self.on_progress, self.on_done, self.on_error = on_progress, on_done, on_error
        self.status = "queued"
        self.started = self.cancelled_at = None
        self._pool = pool

    @property
    def cancelled(self) -> bool:
        return self.status == "cancelled" or self.cancelled_at is not None

    @property
    def finished(self) -> bool:
        return self.status in ("done", "failed", "cancelled")

    def cancel(self) -> None:
        """Stop this job: dropped if queued; asked to stop, then killed, if running."""
        self._pool._cancel(self)

    def _drop_callbacks(self) -> None:
        self.on_progress = self.on_done = self.on_error = None


class _Worker:
    def __init__(self, pool: "JobPool"):
        self.conn, child = _CTX.Pipe()
        self.flag = _CTX.Event()
        self.process = _CTX.Process(target=_worker_main, args=(child, self.flag, pool.warm),
                                    daemon=True, name="rattle-worker")
        # Ctrl-C in a terminal signals the whole process group; a worker is stopped by the
        # server, never by that, so it starts (and stays) with SIGINT blocked
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            self.process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        child.close()
        self.job: Job | None = None
        self.dead = False
        #: Whether the process has warmed up and takes jobs.
        self.ready = False
        self.started = time.monotonic()
        self.reader = threading.Thread(target=pool._read, args=(self,), daemon=True,
                                       name="rattle-worker-reader")
        self.reader.start()


class JobPool:
    """A few worker processes and one fair queue (see the module docstring)."""

    _ids = itertools.count(1)

    def __init__(self, size: int = 2, grace: float = 2.0, warm: Callable[[], Any] | None = None):
        self.size, self.grace, self.warm = size, grace, warm
        self._lock = threading.RLock()
        self._queue: collections.deque[Job] = collections.deque()
        self._closed = False
        self._quick_deaths = 0
        self._workers = [_Worker(self) for _ in range(size)]
        self._monitor = threading.Thread(target=self._watch, daemon=True, name="rattle-job-monitor")
        self._monitor.start()
        _POOLS.add(self)

    # ----- requests ---------------------------------------------------------------------------

    def submit(self, owner: tuple, fn: Callable, args: tuple = (), kwargs: dict | None = None, *,
               time_limit: float = 60.0, on_progress=None, on_done=None, on_error=None) -> Job:
        """Queue ``fn(*args, **kwargs)`` for ``owner`` (``(session, kind)``), replacing its last."""
        job = Job(owner, fn, args, dict(kwargs or {}), time_limit, on_progress, on_done, on_error, self)
        with self._lock:
            if self._closed or not self._workers:
                raise RuntimeError("background work is unavailable on this server")
            for other in [j for j in self._queue if j.owner == owner]:
                self._cancel(other)
            for w in self._workers:
                if w.job is not None and w.job.owner == owner:
                    self._cancel(w.job)
            self._queue.append(job)
            self._dispatch()
        return job

    def cancel_session(self, session: Any) -> None:
        """Cancel every job of ``session`` (its owners are ``(session, kind)``)."""
        with self._lock:
            jobs = [j for j in self._queue if j.owner[0] == session]
            jobs += [w.job for w in self._workers if w.job is not None and w.job.owner[0] == session]
            for j in jobs:
                self._cancel(j)

    def pending(self, session: Any = None) -> list[Job]:
        """Jobs queued or running (of ``session`` only, if given)."""
        with self._lock:
            jobs = list(self._queue) + [w.job for w in self._workers if w.job is not None]
        return [j for j in jobs if session is None or j.owner[0] == session]

    def worker_pids(self, job: Job | None = None) -> list[int]:
        """Process ids of the live workers (only the one running ``job``, if given)."""
        with self._lock:
            return [w.process.pid for w in self._workers if w.process.is_alive() and not w.dead
                    and (job is None or w.job is job)]

    def shutdown(self) -> None:
        with self._lock:
            self._closed = True
            for j in list(self._queue):
                self._cancel(j)
            workers, self._workers = self._workers, []
        for w in workers:
            w.dead = True
            try:
                w.conn.send(None)
            except Exception:
                pass
            w.process.join(timeout=1.0)
            if w.process.is_alive():
                w.process.kill()
                w.process.join(timeout=2.0)
            w.conn.close()

    # ----- internals (under the lock) -----------------------------------------------------------

    def _cancel(self, job: Job) -> None:
        with self._lock:
            if job.finished:
                return
            job._drop_callbacks()
            if job.status == "queued":
                job.status = "cancelled"
                try:
                    self._queue.remove(job)
                except ValueError:
                    pass
                return
            job.cancelled_at = time.monotonic()
            for w in self._workers:
                if w.job is job:
                    w.flag.set()

    def _dispatch(self) -> None:
        with self._lock:
            for w in self._workers:
                if not self._queue:
                    return
                if w.job is not None or w.dead or not w.ready:
                    continue
                job = self._queue.popleft()
                w.flag.clear()
                try:
                    w.conn.send((job.id, job.fn, job.args, job.kwargs))
                except Exception as exc:  # e.g. arguments that cannot be pickled
                    self._finish(job, "failed", error=f"the job could not be started: {exc}")
                    continue
                job.status, job.started, w.job = "running", time.monotonic(), job

    def _finish(self, job: Job, status: str, result: Any = None, error: str = "") -> None:
        """Mark ``job`` finished and call its callback (outside the lock)."""
        with self._lock:
            was_cancelled = job.cancelled_at is not None or job.status == "cancelled"
            job.status = "cancelled" if was_cancelled else status
            cb = None if was_cancelled else (job.on_done if status == "done" else job.on_error)
            job._drop_callbacks()
            job.args = job.kwargs = ()
        if cb is not None:
            try:
                cb(result if status == "done" else error)
            except Exception as exc:
                log.warning("job callback failed: %s: %s", type(exc).__name__, exc)

    def _read(self, w: _Worker) -> None:
        """Reader thread of one worker: progress and outcomes, until the process ends."""
        while True:
            try:
                kind, job_id, payload = w.conn.recv()
            except (EOFError, OSError, TypeError, ValueError):
                break
            # each message is handled in a call of its own: a local of this loop would keep the
            # last callback (and so its closed session's whole page) alive while recv() waits
            self._handle(w, kind, job_id, payload)
            del payload
        if not self._closed and not w.dead:
            self._replace(w, "the worker process ended unexpectedly")

    def _handle(self, w: _Worker, kind: str, job_id: int, payload: Any) -> None:
        """One message of ``w``'s job: its progress, result or failure, or the worker ready."""
        if kind == "ready":
            with self._lock:
                w.ready = True
            self._dispatch()
            return
        with self._lock:
            job = w.job if w.job is not None and w.job.id == job_id else None
            if job is not None and kind != "progress":
                w.job = None
        if job is None:
            return
        if kind == "progress":
            cb = job.on_progress
            if cb is not None and job.cancelled_at is None:
                try:
                    cb(float(payload))
                except Exception as exc:
                    log.warning("job progress callback failed: %s", exc)
            return
        self._finish(job, "done" if kind == "done" else "failed", payload, payload)
        self._dispatch()

    def _replace(self, w: _Worker, reason: str) -> None:
        """Kill ``w`` (if alive), fail its job with ``reason``, and start a new worker."""
        with self._lock:
            if w.dead and w not in self._workers:
                return
            w.dead = True
            job, w.job = w.job, None
            # a worker that cannot even start would be replaced for ever: stop after three
            quick = job is None and time.monotonic() - w.started < 10.0 and reason != "cancelled"
            self._quick_deaths = self._quick_deaths + 1 if quick else 0
            fresh = None
            exiting = not threading.main_thread().is_alive()  # the interpreter is shutting down
            if w in self._workers and not self._closed and not exiting and self._quick_deaths < 3:
                try:
                    fresh = _Worker(self)
                except RuntimeError:  # the interpreter is shutting down
                    self._closed = True
            if fresh is not None:
                self._workers[self._workers.index(w)] = fresh
            elif w in self._workers:
                self._workers.remove(w)
                if not self._workers:
                    log.error("job pool: worker processes fail to start; background work is off")
                    for j in list(self._queue):
                        self._queue.remove(j)
                        threading.Thread(target=self._finish, daemon=True,
                                         args=(j, "failed", None, "background work is unavailable "
                                               "on this server (worker processes fail to start)")).start()
        if w.process.is_alive():
            w.process.kill()
        w.process.join(timeout=5.0)
        if reason != "cancelled":
            log.warning("job pool: a worker process ended after %.1f s (exit code %s): %s",
                        time.monotonic() - w.started, w.process.exitcode, reason)
        try:
            w.conn.close()
        except OSError:
            pass
        if job is not None:
            self._finish(job, "failed", error=reason)
        self._dispatch()

    def _watch(self) -> None:
        """Kill jobs past their time limit, or still running ``grace`` s after a cancel."""
        while not self._closed:
            time.sleep(0.2)
            now = time.monotonic()
            with self._lock:
                busy = [(w, w.job) for w in self._workers if w.job is not None and not w.dead]
                cold = [w for w in self._workers
                        if not w.ready and not w.dead and now - w.started > WARM_LIMIT]
            for w in cold:
                self._replace(w, f"the worker process did not warm up within {WARM_LIMIT:g} s")
            for w, job in busy:
                if job.cancelled_at is not None and now - job.cancelled_at > self.grace:
                    self._replace(w, "cancelled")
                elif job.started is not None and now - job.started > job.time_limit:
                    self._replace(w, f"stopped after {job.time_limit:g} s, the time limit of one "
                                     "job on this server; try fewer values or periods")


_POOLS: "weakref.WeakSet[JobPool]" = weakref.WeakSet()
_pool: JobPool | None = None
_pool_lock = threading.Lock()


def pool(size: int = 2, warm: Callable[[], Any] | None = None) -> JobPool:
    """The server's job pool, started on first use (``warm`` runs in each worker first)."""
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = JobPool(size=size, warm=warm)
        return _pool


@atexit.register
def _shutdown() -> None:
    for p in list(_POOLS):
        p.shutdown()

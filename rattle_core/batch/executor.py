"""Where chunks run: in this process, one after the other, or as tasks on a Dask cluster.

* :func:`run_chunks` is the one loop that sweeps and maps share: it runs a list of chunk
  tasks, reports progress after each, polls ``cancel`` and returns the chunks done, in task
  order.  Locally each chunk already uses every core (a ``numba.prange`` kernel), so the chunks
  run one at a time; on Dask they run on the workers and come back as they finish.
* :func:`connect` opens a Dask client: ``"local"`` starts a ``LocalCluster`` of one-thread
  workers, anything else is a scheduler address (``tcp://host:port``).  :func:`dask_session`
  holds one for the length of a command (the CLI); :func:`shared_client` keeps one per address
  for the life of the process (the dashboard), closed at exit.
"""
from __future__ import annotations

import atexit
import contextlib
import os
import re
import threading
from typing import Any, Callable, Iterator, Sequence

from ..model.params import check_cancel, check_progress

_SCHEDULER_RE = re.compile(r"^(tcp|tls|ws|wss|inproc)://[^\s/]+$")
#: Workers of a ``"local"`` cluster unless told otherwise.
LOCAL_WORKERS = 2


def run_chunks(fn: Callable[..., dict], tasks: Sequence[tuple], sizes: Sequence[int], *,
               executor: Any = None, progress: Callable[[int, int], Any] | None = None,
               cancel: Callable[[], bool] | None = None) -> tuple[list, bool]:
    """Run ``fn(*task)`` for every task; return ``(results in task order, cancelled)``.

    Parameters
    ----------
    fn : callable
        The chunk function; on Dask it must pickle (a module-level function).
    tasks : sequence of tuple
        Arguments of each call.
    sizes : sequence of int
        Items in each task, for ``progress(done, total)``, called after each chunk.
    executor : dask.distributed.Client, optional
        Run the tasks on this cluster instead of here.
    cancel : callable() -> bool, optional
        Polled before each local chunk and after each finished Dask task; once it returns
        True, the chunks done so far are returned (on Dask the others are cancelled).
    """
    progress, cancel = check_progress(progress), check_cancel(cancel)
    total = int(sum(sizes))
    done = 0
    if executor is None:
        parts: list = []
        for task, size in zip(tasks, sizes):
            if cancel is not None and cancel():
                return parts, True
            parts.append(fn(*task))
            done += size
            if progress is not None:
                progress(done, total)
        return parts, False
    from dask.distributed import as_completed

    # as_completed needs a current client; a shared client is nobody's default
    with executor.as_current():
        futures = [executor.submit(fn, *task, pure=False) for task in tasks]
        index = {f.key: i for i, f in enumerate(futures)}
        found: dict[int, Any] = {}
        for fut, res in as_completed(futures, with_results=True):
            i = index[fut.key]
            found[i] = res
            done += sizes[i]
            if progress is not None:
                progress(done, total)
            if cancel is not None and cancel() and len(found) < len(futures):
                for f in futures:
                    f.cancel()
                return [found[k] for k in sorted(found)], True
    return [found[k] for k in sorted(found)], False


def default_threads() -> int:
    """Threads numba uses for a local chunk (``NUMBA_NUM_THREADS`` or the core count)."""
    return int(os.environ.get("NUMBA_NUM_THREADS", os.cpu_count() or 1))


# ----- Dask clients ---------------------------------------------------------------------------

def check_scheduler(text: Any) -> str:
    """A scheduler choice cleaned: ``""`` (this process), ``"local"`` or an address.

    Raises ``ValueError`` naming the value and what is allowed.
    """
    s = "" if text is None else str(text).strip()
    if s in ("", "local") or _SCHEDULER_RE.match(s):
        return s
    raise ValueError(f"Dask scheduler {s!r} is not understood: leave it empty for this "
                     "process's cores, write 'local' for a Dask LocalCluster, or tcp://host:port")


def connect(address: str, workers: int = LOCAL_WORKERS, timeout: str = "10s"
            ) -> tuple[Any, Callable[[], None]]:
    """A new ``dask.distributed.Client`` for ``address`` (``"local"`` or a scheduler address),
    and the function that closes it (and its local cluster).

    Raises ``ConnectionError`` with a one-line message when Dask is missing or the scheduler
    cannot be reached within ``timeout``; ``ValueError`` for a bad address or worker count.
    """
    address = check_scheduler(address)
    if address == "":
        raise ValueError("connect needs 'local' or a scheduler address, got ''")
    from ..model.params import check_int
    workers = check_int("workers", workers, 1, 256)
    try:
        from dask.distributed import Client
    except ImportError:
        raise ConnectionError("Dask (dask.distributed) is not installed; run on this "
                              "process's cores instead") from None
    try:
        if address == "local":
            cluster = local_cluster(workers)
            client = Client(cluster, set_as_default=False)
            return client, lambda: close_local(client, cluster)
        client = Client(address, timeout=timeout, set_as_default=False)
    except Exception as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise ConnectionError(f"Dask scheduler {address!r}: cannot connect ({text})") from None
    return client, client.close


#: Retries of one message between a Dask worker and its scheduler.  Dask's default is none:
#: a connection the scheduler closed while its process was busy (a loaded machine) fails a
#: worker's heartbeat, which Dask then logs with a traceback and recovers from on the next one.
COMM_RETRIES = 3


def local_cluster(workers: int = LOCAL_WORKERS) -> Any:
    """A Dask ``LocalCluster`` of ``workers`` one-thread workers, retrying a failed message."""
    import dask
    from dask.distributed import LocalCluster

    # set before the cluster starts: each worker process takes the configuration of this one
    dask.config.set({"distributed.comm.retry.count": COMM_RETRIES})
    return LocalCluster(n_workers=int(workers), threads_per_worker=1, dashboard_address=None)


def close_local(client: Any, cluster: Any, timeout: float = 20.0) -> None:
    """Close ``client`` and its local ``cluster``, and wait until the worker processes have ended.

    ``cluster.close()`` may give up (its timeout, on a loaded machine) while a worker
    process still runs: that process outlived the command, and the queues each nanny shares
    with its worker were released only at interpreter exit, too late for the resource
    tracker, which reported leaked semaphores.  Here each worker process is joined (killed
    after ``timeout``), its nanny's record of it released, and what is left collected while
    the interpreter is whole.
    """
    import gc

    # each nanny's WorkerProcess, and the multiprocessing.Process under it
    records = [getattr(nanny, "process", None) for nanny in list(getattr(cluster, "workers", {}).values())]
    processes = [getattr(getattr(r, "process", None), "_process", None) for r in records]
    for closing in (client.close, lambda: cluster.close(timeout=timeout)):
        try:
            closing()
        except Exception:  # a close that timed out: its worker processes are ended below
            pass
    for process in processes:
        if process is None:
            continue
        process.join(timeout)
        if process.is_alive():
            process.kill()
            process.join(5)
    for record in records:
        if getattr(record, "process", None) is not None:
            try:
                record.mark_stopped()  # what the nanny does when it sees its worker end
            except Exception:
                pass
    del records, processes
    gc.collect()


@contextlib.contextmanager
def dask_session(address: str | None, workers: int = LOCAL_WORKERS) -> Iterator[Any]:
    """A Dask client for the ``with`` block (None when ``address`` is empty: run here)."""
    if not address:
        yield None
        return
    client, close = connect(address, workers)
    try:
        yield client
    finally:
        close()


_shared_lock = threading.Lock()
_shared: dict[str, tuple[Any, Callable[[], None]]] = {}


def shared_client(address: str | None) -> Any:
    """One client per address for the whole process (None for ``""``: run here).

    A client that lost its scheduler is replaced; all are closed when the process exits.
    """
    address = check_scheduler(address)
    if address == "":
        return None
    with _shared_lock:
        entry = _shared.get(address)
        if entry is not None and entry[0].status == "running":
            return entry[0]
        if entry is not None:
            _close_quietly(entry[1])
        _shared[address] = connect(address, timeout="5s")
        return _shared[address][0]


def _close_quietly(close: Callable[[], None]) -> None:
    try:
        close()
    except Exception:  # a cluster already gone is closed enough
        pass


@atexit.register
def close_shared() -> None:
    """Close every shared client (and local cluster) now."""
    with _shared_lock:
        for _, close in _shared.values():
            _close_quietly(close)
        _shared.clear()

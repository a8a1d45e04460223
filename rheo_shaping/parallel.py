"""One seam for the expensive loops: any :class:`concurrent.futures.Executor`.

The d sweep, the paper study, the diagnosis fits, the diagnosis benchmark, the
abort campaign and the cell calibration hand their independent tasks to
:func:`run_tasks`, which takes whatever executor the caller opened:

* ``executor_from_spec(None)`` or ``"local"``: a process pool on this machine
  (``"local:N"`` for N worker processes; the default is one per core);
* ``"serial"``: every task in the calling process, in order (no pool);
* ``"dask://HOST:PORT"``: an existing Dask cluster, through the
  ``dask.distributed`` client's executor (``pip install "dask[distributed]"``).

What a task needs travels with it: :func:`run_tasks` sends the ``shared``
object once per chunk of tasks (not once per task), so no worker depends on
module globals or on what an earlier task left behind, and a chunk can run on
any machine.  Seeds belong in the items, so a case reproduces wherever it runs.
"""
from __future__ import annotations

import contextlib
import os
import threading
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from typing import Any, Callable, Iterator, Sequence, TypeVar

T = TypeVar("T")
R = TypeVar("R")

#: How long [s] a ``dask://`` executor waits for its scheduler to answer.
CONNECT_TIMEOUT_S = 10.0

SPEC_HELP = ("'local' (a process pool, one worker per core), 'local:N' (N workers), "
             "'serial' (no pool) or 'dask://HOST:PORT' (an existing Dask scheduler)")


class SerialExecutor(Executor):
    """Runs each task at submission, in the calling process."""

    def submit(self, fn, /, *args, **kwargs) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future
            future.set_exception(exc)
        return future


def local_pool(workers: int) -> ProcessPoolExecutor:
    """A process pool; forked workers start fast, but a process with threads (a ROS node,
    whose DDS threads Python does not see, a Dask client) spawns them, since fork copies
    only the calling thread."""
    import multiprocessing
    import sys
    single = threading.active_count() == 1 and "rclpy" not in sys.modules
    method = "fork" if single and os.name == "posix" else "spawn"
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(method))


@contextlib.contextmanager
def executor_from_spec(spec: str | None = None, jobs: int | None = None) -> Iterator[Executor]:
    """The executor named by ``spec`` (see the module docstring), closed on exit.

    ``jobs`` is the default size of a local pool; ``jobs == 1`` without a spec
    runs serially.  Raises ``ValueError`` naming the spec for anything else.
    """
    if jobs is not None and jobs < 1:
        raise ValueError(f"jobs = {jobs!r} is invalid: expected at least 1 worker")
    text = "local" if spec is None else str(spec).strip()
    if text == "serial" or (spec is None and jobs == 1):
        yield SerialExecutor()
        return
    if text == "local" or text.startswith("local:"):
        workers = jobs or os.cpu_count() or 1
        if text.startswith("local:"):
            count = text[len("local:"):]
            if not count.isdigit() or int(count) < 1:
                raise ValueError(f"--executor {spec!r}: expected 'local:N' with N >= 1 workers")
            workers = int(count)
        pool = local_pool(workers)
        try:
            yield pool
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        return
    if text.startswith("dask://"):
        address = text[len("dask://"):]
        host, _, port = address.rpartition(":")
        if not host or not port.isdigit():
            raise ValueError(f"--executor {spec!r}: expected dask://HOST:PORT, e.g. "
                             "dask://127.0.0.1:8786")
        try:
            from distributed import Client
        except ImportError:
            raise ValueError(f"--executor {spec!r} needs dask.distributed: "
                             "pip install 'dask[distributed]'") from None
        try:
            client = Client(f"tcp://{address}", timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except OSError as exc:
            raise ValueError(f"--executor {spec!r}: no Dask scheduler answers at "
                             f"{address} ({exc})") from None
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()
        return
    raise ValueError(f"--executor {spec!r} is not an executor: expected {SPEC_HELP}")


def executor_workers(executor: Executor) -> int:
    """How many tasks ``executor`` runs at once (1 when it cannot tell)."""
    if isinstance(executor, ProcessPoolExecutor):
        return int(getattr(executor, "_max_workers", 1))
    client = getattr(executor, "_client", None)
    if client is not None:
        try:
            return max(1, sum(client.nthreads().values()))
        except Exception:  # noqa: BLE001 - a cluster that cannot say: one at a time
            return 1
    return 1


def _run_chunk(fn: Callable[[Any, T], R], shared: Any, items: Sequence[T]) -> list[R]:
    return [fn(shared, item) for item in items]


def run_tasks(executor: Executor | None, fn: Callable[[Any, T], R], shared: Any,
              items: Sequence[T], progress: Callable[[int], None] | None = None,
              chunks_per_worker: int = 4) -> list[R]:
    """``[fn(shared, item) for item in items]``, the items split into chunks on ``executor``.

    ``fn`` must be a module-level function (it is pickled); ``shared`` goes with every
    chunk.  ``progress(k)`` is called with the number of items each finished chunk held.
    Results come back in the order of ``items``; an exception in a task is raised here.
    """
    items = list(items)
    if not items:
        return []
    if executor is None or isinstance(executor, SerialExecutor):
        results: list[R] = []
        for item in items:                          # in order, progress after every task
            results.append(fn(shared, item))
            if progress is not None:
                progress(1)
        return results
    n_chunks = min(len(items), max(1, executor_workers(executor) * chunks_per_worker))
    bounds = [round(i * len(items) / n_chunks) for i in range(n_chunks + 1)]
    futures = {executor.submit(_run_chunk, fn, shared, items[a:b]): (a, b)
               for a, b in zip(bounds[:-1], bounds[1:]) if b > a}
    chunks: dict[int, list[R]] = {}                 # first item's index -> the chunk's results
    for future in as_completed(futures):
        a, b = futures[future]
        chunks[a] = future.result()
        if progress is not None:
            progress(b - a)
    return [r for a in sorted(chunks) for r in chunks[a]]

"""Where tile jobs run: in this process, on local worker processes, or on a Dask cluster.

One seam: :meth:`Runner.map` applies a pure function to a list of jobs, ``fn(shared, job)``
for each, and returns the results in the jobs' order, whoever computed them. The proof
and the rival checks cut their work into tile jobs whose results depend only on the site
(:mod:`planner.verify.tiles`), so a plan is byte-identical whatever runs it.

* :class:`InProcess` (the default): one job after the other.
* :class:`LocalProcesses` (``--workers N``): a ``ProcessPoolExecutor`` of N spawned processes,
  kept for the runner's life (``with`` block); ``shared`` is sent with each job.

Jobs are taken from an iterable a few at a time (two in flight per worker), so a large site's
jobs are made as they are needed, not all held in memory.
* :class:`DaskCluster` (``--scheduler ADDRESS``): a ``dask.distributed`` client; ``shared`` is
  scattered to every worker once per :meth:`~Runner.map`.

Progress goes to stderr on a terminal only (one line, rewritten), never into any output.
"""

from __future__ import annotations

import sys
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

from planner.errors import InputError, UsageError

CONNECT_TIMEOUT_S = 10.0
"""How long ``--scheduler ADDRESS`` waits for the scheduler before giving up [s]; an address where
nothing listens (connection refused) or a host name that does not resolve fails at once."""


class Runner:
    """Runs ``fn(shared, job)`` for every job; results in the jobs' order. Use as a context manager."""

    workers = 1
    description = "in process"

    def map(self, fn: Callable[[Any, Any], Any], shared: Any, jobs: Iterable[Any], label: str = "",
            total: int = 0) -> list:
        """``[fn(shared, job) for job in jobs]``; ``jobs`` is consumed lazily (a few jobs in flight per
        worker, so that a large site's jobs are never all in memory at once); ``total`` is for progress."""
        out = []
        for job in jobs:
            out.append(fn(shared, job))
            _progress(label, len(out), total)
        return out

    def close(self) -> None:
        """Release the workers (nothing to release in process)."""

    def __enter__(self) -> Runner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class InProcess(Runner):
    """Every job in this process, in order (the default)."""


class LocalProcesses(Runner):
    """Jobs on ``workers`` local processes (spawned: no state is inherited from this one)."""

    def __init__(self, workers: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self.workers = workers
        self.description = f"{workers} local processes"
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))

    def map(self, fn, shared, jobs, label="", total=0):
        return _bounded(lambda job: self._pool.submit(fn, shared, job), jobs, 2 * self.workers, label, total)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskCluster(Runner):
    """Jobs on the workers of the Dask scheduler at ``address`` (``tcp://host:8786``)."""

    def __init__(self, address: str):
        try:
            from distributed import Client
        except ImportError:  # pragma: no cover - a dependency of the package
            raise UsageError("`scheduler` needs dask.distributed: pip install 'vlp-plan[cluster]'") from None
        try:
            _reachable(address)
            self._client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"`scheduler` {address}: no Dask scheduler answers there ({_first_line(exc)}); "
                             "start one (dask scheduler) or check the address") from None
        self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))
        self.description = f"Dask scheduler {address} ({self.workers} workers)"

    def map(self, fn, shared, jobs, label="", total=0):
        data = self._client.scatter(shared, broadcast=True, hash=False)  # a key of its own: cancelled below
        try:
            return _bounded(lambda job: self._client.submit(fn, data, job, pure=False), jobs, 2 * self.workers,
                            label, total)
        finally:
            self._client.cancel([data])

    def close(self) -> None:
        self._client.close()


def _reachable(address: str) -> None:
    """Raise OSError at once where a TCP scheduler address refuses or does not resolve; Dask's client
    would retry until :data:`CONNECT_TIMEOUT_S`, as for a scheduler still starting. Other schemes pass."""
    import socket

    from distributed.comm import parse_address, parse_host_port

    scheme, location = parse_address(address)
    if scheme == "tcp":
        socket.create_connection(parse_host_port(location, 8786), timeout=CONNECT_TIMEOUT_S).close()


def runner(workers: int = 1, scheduler: str | None = None) -> Runner:
    """The runner the command line asks for: a Dask client, ``workers`` local processes, or in process."""
    if scheduler is not None and workers > 1:
        raise UsageError("`workers` and `scheduler` exclude each other: the scheduler's workers run the tiles")
    if scheduler is not None:
        return DaskCluster(scheduler)
    if workers > 1:
        return LocalProcesses(workers)
    return InProcess()


def _bounded(submit: Callable[[Any], Any], jobs: Iterable[Any], in_flight: int, label: str, total: int) -> list:
    """Submit ``jobs`` keeping at most ``in_flight`` unfinished; their results in the jobs' order."""
    out: list = []
    pending: deque = deque()
    for job in jobs:
        pending.append(submit(job))
        if len(pending) >= in_flight:
            out.append(pending.popleft().result())
            _progress(label, len(out), total)
    while pending:
        out.append(pending.popleft().result())
        _progress(label, len(out), total)
    return out


def _on_terminal() -> bool:
    return sys.stderr.isatty()


def _progress(label: str, done: int, total: int) -> None:
    """``label: done/total tiles`` on stderr, rewritten in place; only on a terminal and for several jobs."""
    if not label or total < 2 or not _on_terminal():
        return
    end = "\n" if done == total else ""
    print(f"\r  {label}: {done}/{total} tiles", end=end, file=sys.stderr, flush=True)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__

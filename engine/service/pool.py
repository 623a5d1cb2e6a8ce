"""The service's worker processes, its deadlines and its KB, reloaded atomically.

Requests run in worker processes (each a Pebble ``ProcessPool`` of one process, started with
the served KB by :func:`~.worker.start_worker`, one request at a time, a worker that dies
replaced). Requests wait their turn for a free worker; a request goes to the free worker that
last answered the same query, else the same object, else the one the object's id is given to
(a stable hash): the caches a plan warms (the object's candidates, its torque tables, the
arms' inverse-kinematics answers for its poses) serve the next plan of that object.

Processes rather than threads: planning is numpy and Python that holds the GIL for most of a
plan, so two threads would not plan twice as fast; each process has state of its own, so
nothing mutable is shared between concurrent requests; and a request past its deadline can be
stopped for real: its worker is ended and a fresh one started (a thread cannot be stopped),
while every other request goes on. Workers are forked
from a fork server that imported the engine once (:data:`~.worker.PRELOAD`), so a new worker
is ready in a fraction of a second.

:class:`Service` holds the KB being served and its pool. :meth:`Service.reload` loads the
KB folder again (a private snapshot of it, through the validated cache,
:func:`~handover.engine.load.cache.load_kb_cached`, its robots' URDFs parsed);
a KB that does not validate raises its KBError and changes nothing; a valid one gets a new
pool, which takes the requests that come after, while the old pool finishes those it has and
then stops. A request is answered by the KB it started with, never by a mix.
"""

from __future__ import annotations

import asyncio
import multiprocessing
import shutil
import tempfile
import threading
import time
import zlib
from collections.abc import Callable, Hashable
from concurrent.futures import CancelledError
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from handover.engine.assets.lru import LRU
from handover.engine.service.worker import (
    PRELOAD,
    AnswerMemo,
    Reply,
    error_body,
    ping,
    start_worker,
)

if TYPE_CHECKING:
    from pebble import ProcessPool

    from handover.engine.store.kb import KB

__all__ = ["ServedKB", "WorkerPool", "Service", "DeadlineExceeded", "Busy", "load_served"]


class DeadlineExceeded(Exception):
    """A request was not answered within its deadline (its worker was stopped)."""


class Busy(Exception):
    """More requests are waiting than the service takes at once."""


@dataclass(frozen=True)
class ServedKB:
    """The KB a pool serves: the KB, its folder, content digest, counts, warnings (as
    ``kb validate --json`` gives them) and when it was loaded (s since the epoch).

    snapshot : a private copy of the folder taken when it was loaded, which the KB reads its
    files from (a robot's URDF, the objects' meshes, read when a plan first needs them):
    edits to the folder are served from the next reload that validates them, never before.
    Removed by :meth:`discard` when no pool serves it any more."""

    kb: KB
    root: Path
    digest: str
    counts: dict[str, int]
    warnings: list[dict]
    loaded_at: float
    snapshot: Path | None = None

    def discard(self) -> None:
        """Remove the snapshot (its pool has stopped)."""
        if self.snapshot is not None:
            shutil.rmtree(self.snapshot, ignore_errors=True)

    def describe(self) -> dict[str, Any]:
        return {"root": str(self.root), "digest": self.digest, "counts": self.counts,
                "warnings": len(self.warnings), "loaded_at": round(self.loaded_at, 3)}


def load_served(kb_dir: Path | str | None, cache_dir: Path | None) -> ServedKB:
    """Load and check the KB folder (through the cache in ``cache_dir``, None: the full
    load), and parse its robots' URDFs (every plan needs its robot's: a broken one would
    stop them all, so it is refused here, as on a reload). Raises KBError (every problem,
    file:line:col) or UsageError (no such folder)."""
    from handover.engine.errors import KBError
    from handover.engine.load.cache import kb_digest, load_kb_cached
    from handover.engine.load.lint import lint_robot
    from handover.engine.store.kb import resolve_kb_dir
    from handover.engine.tools.answer import issue_json

    root = resolve_kb_dir(kb_dir)
    snapshot = Path(tempfile.mkdtemp(prefix="handover-kb-"))
    try:
        files = snapshot / "kb"
        shutil.copytree(root, files, ignore=shutil.ignore_patterns("__pycache__", ".*"))
        digest = kb_digest(files)
        kb = load_kb_cached(files, cache_dir)
        broken = [issue for robot in kb.robots.values() for issue in lint_robot(kb, robot)
                  if issue.severity == "error"]
        if broken:
            raise KBError(sorted(broken), warnings=list(kb.warnings))
    except BaseException:
        shutil.rmtree(snapshot, ignore_errors=True)
        raise
    return ServedKB(kb, root, digest, kb.counts(), [issue_json(i) for i in kb.warnings],
                    time.time(), snapshot)


AFFINITY_KEPT = 4096
"""Queries and objects whose last worker the pool remembers (to send the next request about
them there, :meth:`WorkerPool.choose`)."""


class WorkerPool:
    """``workers`` processes serving one KB. ``db_root`` : the grasp database folder (None:
    generate candidates). ``memo_bytes`` : the memo of the answers they gave (``answers``,
    in this process: a request asked again is answered from it, whichever worker made the
    answer; a new KB gets a new pool, and so a new memo)."""

    def __init__(self, served: ServedKB, workers: int, db_root: Path | None, memo_bytes: int):
        from pebble import ProcessPool

        if workers < 1:
            raise ValueError(f"a pool needs at least one worker, got {workers}")
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(list(PRELOAD))
        self.served = served
        self.workers = workers
        self.answers = AnswerMemo(memo_bytes)
        initargs = (served.kb, None if db_root is None else str(db_root))
        self._pools: list[ProcessPool] = [
            ProcessPool(max_workers=1, initializer=start_worker, initargs=initargs,
                        context=context) for _ in range(workers)]
        self._busy = [False] * workers  # a request running in each worker
        self._free = asyncio.Semaphore(workers)  # requests wait here for a free worker, in turn
        self._answered: LRU[Hashable, int] = LRU(AFFINITY_KEPT)  # key -> last worker

    def choose(self, affinity: tuple[Hashable, ...] = ()) -> int:
        """The free worker for a request about ``affinity`` (its keys, the most telling
        first: the query, then its object's id): the one that last answered a request with
        one of them, in that order, when free; else the one the object's id is given to (a
        stable hash of it), when free; else the first free one. Called in the event loop
        only, when one is free."""
        free = [i for i, busy in enumerate(self._busy) if not busy]
        for key in affinity:
            last = self._answered.get(key)
            if last in free:
                return last
        named = [key for key in affinity if isinstance(key, str)]  # an object's id
        if named:
            given = zlib.crc32(named[-1].encode("utf-8")) % self.workers
            if given in free:
                return given
        return free[0]

    async def call(self, function: Callable[..., Reply], *args: Any, deadline: float,
                   affinity: tuple[Hashable, ...] = ()) -> Reply:
        """Run ``function(*args)`` in a free worker (:meth:`choose` with ``affinity``; while
        none is, the request waits its turn); DeadlineExceeded after ``deadline`` s, waiting
        included (the worker running it is stopped and replaced)."""
        worker, future = None, None
        try:
            async with asyncio.timeout(deadline), self._free:
                worker = self.choose(affinity)
                self._busy[worker] = True
                future = self._pools[worker].schedule(function, args=args)
                reply = await asyncio.wrap_future(future)
                for key in affinity:  # what this worker's caches now hold
                    self._answered.put(key, worker)
                return reply
        except TimeoutError:
            if future is not None:
                future.cancel()
            raise DeadlineExceeded(deadline) from None
        except (CancelledError, asyncio.CancelledError):
            if future is None or not future.cancelled():
                raise  # the request itself was cancelled (its client went away)
            raise DeadlineExceeded(deadline) from None
        except Exception as e:  # noqa: BLE001 - a worker that died while answering
            return Reply(500, error_body("worker_died", f"the worker ended while answering "
                                         f"({type(e).__name__}: {e}); it was replaced"))
        finally:
            if worker is not None:
                self._busy[worker] = False

    async def ready(self, deadline: float) -> list[int]:
        """Start every worker and return their process ids once each has answered (KB and
        grasp database loaded). Raises HandoverError (one line: the CLI's error, not a
        traceback) when a worker cannot start or some do not answer within ``deadline`` s."""
        from handover.engine.errors import HandoverError

        futures = [pool.schedule(ping) for pool in self._pools]
        try:
            async with asyncio.timeout(deadline):
                return list(await asyncio.gather(*map(asyncio.wrap_future, futures)))
        except TimeoutError:
            raise HandoverError(f"the worker processes did not all start within {deadline:g} "
                                "s") from None
        except Exception as e:  # noqa: BLE001 - the worker's own error, said in one line
            raise HandoverError(f"a worker process did not start: {type(e).__name__}: "
                                f"{e}") from None

    def pids(self) -> list[int]:
        """The worker processes' ids (those alive now)."""
        found: list[int] = []
        for pool in self._pools:
            manager = getattr(pool, "_pool_manager", None)
            workers = getattr(getattr(manager, "worker_manager", None), "workers", {})
            found.extend(int(pid) for pid in workers)
        return sorted(found)

    def close(self, wait: bool = False) -> None:
        """Stop taking requests; the workers end when those they have are answered. With
        ``wait``, return when they have."""
        for pool in self._pools:
            pool.close()
        if wait:
            for pool in self._pools:
                pool.join()
            self.served.discard()
        else:  # join in the background: the old pool of a reload ends on its own
            def join() -> None:
                for pool in self._pools:
                    pool.join()
                self.served.discard()

            threading.Thread(target=join, daemon=True).start()

    def stop(self) -> None:
        """Stop now: every worker ended, waiting requests dropped."""
        for pool in self._pools:
            pool.stop()
        for pool in self._pools:
            pool.join()
        self.served.discard()


@dataclass
class Service:
    """The KB served and its pool, the limits, and the reloads (one at a time).

    kb_dir : the KB folder (None: ``$HANDOVER_KB`` or the built-in one). db_root : the grasp
    database folder (None: none, and the KB loaded in full each time). deadline : the longest
    a request may take (s); a request may ask for less. max_pending : requests taken at once
    (running or waiting), beyond which the service answers 503.
    """

    kb_dir: Path | None
    db_root: Path | None
    workers: int = 2
    deadline: float = 30.0
    max_pending: int = 64
    memo_bytes: int = 64 * 2**20
    pool: WorkerPool | None = None
    pending: int = 0
    reloads: int = 0
    _lock: asyncio.Lock = field(default_factory=asyncio.Lock)

    def _cache_dir(self) -> Path | None:
        from handover.engine.load.cache import kb_cache_dir

        return None if self.db_root is None else kb_cache_dir(self.db_root)

    async def start(self) -> None:
        """Load the KB and start the pool; return when a worker answers."""
        served = await asyncio.to_thread(load_served, self.kb_dir, self._cache_dir())
        self.pool = WorkerPool(served, self.workers, self.db_root, self.memo_bytes)
        await self.pool.ready(deadline=max(self.deadline, 120.0))

    @property
    def served(self) -> ServedKB:
        if self.pool is None:
            raise RuntimeError("the service is not started")
        return self.pool.served

    async def run(self, function: Callable[..., Reply], *args: Any,
                  deadline: float | None = None, key: tuple | None = None,
                  affinity: tuple[Hashable, ...] = ()) -> Reply:
        """Run a task in the current pool within ``deadline`` (at most the service's);
        Busy when ``max_pending`` requests are already in. ``key`` : what decides the
        answer's bytes: an answer the pool's memo holds under it is given at once, and a
        200 answer is kept under it (None: neither). ``affinity`` : what the request is about,
        the most telling first (:meth:`WorkerPool.choose`)."""
        pool = self.pool
        if pool is None:
            raise RuntimeError("the service is not started")
        if key is not None:
            found = pool.answers.get(key)
            if found is not None:
                return Reply(found.status, found.body, found.media_type, found.outcome, True,
                             found.pid, 0.0)
        if self.pending >= self.max_pending:
            raise Busy(self.max_pending)
        limit = self.deadline if deadline is None else min(deadline, self.deadline)
        self.pending += 1
        try:
            reply = await pool.call(function, *args, deadline=limit, affinity=affinity)
        finally:
            self.pending -= 1
        if key is not None and reply.status == 200:
            pool.answers.put(key, reply)
        return reply

    async def reload(self) -> tuple[ServedKB, ServedKB]:
        """Load the KB folder again and serve it: ``(old, new)``. Raises KBError (the old
        KB goes on serving) or UsageError."""
        async with self._lock:
            old = self.served
            served = await asyncio.to_thread(load_served, self.kb_dir, self._cache_dir())
            if served.digest == old.digest:
                served.discard()
                return old, old
            pool = WorkerPool(served, self.workers, self.db_root, self.memo_bytes)
            try:
                await pool.ready(deadline=max(self.deadline, 120.0))
            except BaseException:
                pool.stop()  # and its snapshot
                raise
            previous, self.pool = self.pool, pool
            self.reloads += 1
            assert previous is not None
            previous.close()
            return old, served

    def stop(self) -> None:
        if self.pool is not None:
            self.pool.stop()

"""Where a study's tasks run: in this process, in local worker processes, or on Ray - and the
one loop that runs a batch of tasks on any of them with a retry and Cancel.

Every engine hands out `concurrent.futures.Future`s (Ray's `ObjectRef.future()`), so
`run_batch` is the same whatever runs the tasks: a task that raised, or whose worker died, is
submitted once more and, if it fails again, reported as failed with both errors - never
dropped. Cancel (the `Progress`) stops the pending tasks and sets the flag the running ones
check at their next progress update (local), or cancels them in Ray.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing as mp
from collections.abc import Callable, Sequence
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

from assistant.progress import Cancelled, Progress
from assistant.study import tasks

TaskFn = Callable[..., Any]


@dataclass
class TaskFailure:
    """A task that failed twice: what it was and both errors."""

    item: Any
    errors: list[str]


class Engine:
    """Runs `fn(key, item)` somewhere; subclasses say where."""

    name = "inline"
    workers = 1

    def start(self, key: str, problem: Any, scoring: Any) -> None:
        """Before the first batch: the context is installed in the parent already."""

    def bind(self, progress: Progress | None) -> None:
        """Tasks run here check this progress's Cancel (None: unbind)."""
        tasks.set_cancel_flag(None if progress is None else _ProgressFlag(progress))

    def submit(self, fn: TaskFn, key: str, item: Any) -> cf.Future:
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(key, item))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller like a worker's
            fut.set_exception(exc)
        return fut

    def restart(self) -> None:
        """After a worker died: a fresh pool for the retries."""

    def cancel(self) -> None:
        """Stop everything running (Cancel)."""

    def close(self) -> None:
        """Release the workers."""


class _ProgressFlag:
    """A progress's cancel seen as the `is_set()` flag the tasks check."""

    def __init__(self, progress: Progress):
        self._progress = progress

    def is_set(self) -> bool:
        return self._progress.cancelled


class LocalEngine(Engine):
    """Worker processes forked from this one: they inherit the study's context (the robot,
    the joint-position store) read-only instead of building or receiving it per task."""

    name = "local"

    def __init__(self, workers: int):
        if workers < 1:
            raise ValueError("workers must be >= 1")
        self.workers = int(workers)
        self._ctx = mp.get_context("fork")
        self._flag = self._ctx.Event()
        self._pool: cf.ProcessPoolExecutor | None = None

    def bind(self, progress: Progress | None) -> None:
        """Workers check the shared flag; `cancel` sets it."""

    def _executor(self) -> cf.ProcessPoolExecutor:
        if self._pool is None:
            self._pool = cf.ProcessPoolExecutor(self.workers, mp_context=self._ctx,
                                                initializer=tasks.set_cancel_flag,
                                                initargs=(self._flag,))
        return self._pool

    def submit(self, fn: TaskFn, key: str, item: Any) -> cf.Future:
        return self._executor().submit(fn, key, item)

    def restart(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
        self._pool = None

    def cancel(self) -> None:
        self._flag.set()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)  # running ones stop soon
        self._pool = None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._pool = None


class RayEngine(Engine):
    """The same task function as Ray tasks on a cluster (`address`: "auto", "ray://host:port")
    or a local Ray instance started here (`address` "local", `workers` CPUs). The problem is
    put in the object store once; each Ray worker builds its context on first use."""

    name = "ray"

    def __init__(self, address: str = "local", workers: int | None = None):
        try:
            import ray
        except ImportError:
            raise RuntimeError("Ray is not installed: pip install 'cellteach[cluster]'") \
                from None
        self._ray = ray
        self._started_here = False
        if not ray.is_initialized():
            if address == "local":
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                         configure_logging=False)
            else:
                ray.init(address=address, log_to_driver=False, configure_logging=False)
            self._started_here = True
        self.workers = int(workers or ray.cluster_resources().get("CPU", 1))
        self._remote = ray.remote(max_retries=0, num_cpus=1)(_ray_task)
        self._refs: list[Any] = []
        self._problem_ref: Any = None

    def bind(self, progress: Progress | None) -> None:
        """Ray tasks are stopped by `ray.cancel`."""

    def start(self, key: str, problem: Any, scoring: Any) -> None:
        self._problem_ref = self._ray.put((problem, scoring))

    def submit(self, fn: TaskFn, key: str, item: Any) -> cf.Future:
        ref = self._remote.remote(fn, key, item, self._problem_ref)
        self._refs.append(ref)
        return ref.future()

    def cancel(self) -> None:
        for ref in self._refs:
            with contextlib.suppress(Exception):  # finished or already gone
                self._ray.cancel(ref, force=True)
        self._refs = []

    def close(self) -> None:
        self._refs = []
        if self._started_here:
            self._ray.shutdown()


def _ray_task(fn: TaskFn, key: str, item: Any, problem_and_scoring: Any) -> Any:
    problem, scoring = problem_and_scoring
    tasks.context(key, problem, scoring)  # built once per Ray worker process
    return fn(key, item)


def run_batch(engine: Engine, fn: TaskFn, key: str, items: Sequence[Any],
              progress: Progress, on_result: Callable[[Any, Any], None] | None = None,
              ) -> tuple[list[Any], list[TaskFailure], int, dict[int, list[str]]]:
    """Run `fn(key, item)` for every item; results in the items' order (None where a task
    failed: see the failures), the failures, the number of retries, and every error seen
    by item index (also those of tasks that succeeded when retried).

    A task that raised is run once more. A worker that dies breaks the local pool and loses
    every task in it, not only the one that killed it: the lost tasks run again on a fresh
    pool, and those lost a second time run one at a time, where a loss names its task - that
    one is reported as failed, the others go on.
    """
    n = len(items)
    results: list[Any] = [None] * n
    errors: dict[int, list[str]] = {}
    failures: list[TaskFailure] = []
    lost_once: set[int] = set()
    raised: set[int] = set()
    retries = 0
    done_count = 0
    pending: dict[cf.Future, int] = {}
    alone: list[int] = []  # lost twice: run one at a time

    def submit(i: int) -> None:
        try:
            fut = engine.submit(fn, key, items[i])
        except BrokenProcessPool as exc:
            # The pool broke under another task whose loss is not seen yet (a retry sent in
            # the same round): this one is lost with it, and restarted below like the rest.
            fut = cf.Future()
            fut.set_exception(exc)
        pending[fut] = i

    def fail(i: int, why: str) -> None:
        nonlocal done_count
        errors.setdefault(i, []).append(why)
        failures.append(TaskFailure(items[i], errors[i]))
        done_count += 1

    engine.bind(progress)
    try:
        for i in range(n):
            progress.check()  # an inline engine runs each task in `submit`
            submit(i)
        while pending or alone:
            if not pending:
                submit(alone.pop(0))
            if progress.cancelled:
                raise Cancelled(f"{progress.task or 'study'} cancelled")
            done, _ = cf.wait(list(pending), timeout=0.1, return_when=cf.FIRST_COMPLETED)
            lost: list[int] = []
            for fut in done:
                i = pending.pop(fut)
                exc = fut.exception()
                if exc is None:
                    results[i] = fut.result()
                    done_count += 1
                    if on_result is not None:
                        on_result(items[i], results[i])
                    progress.update(done_count / max(1, n), f"{done_count} of {n} candidates")
                elif isinstance(exc, Cancelled) and progress.cancelled:
                    raise Cancelled(f"{progress.task or 'study'} cancelled")
                elif isinstance(exc, BrokenProcessPool):
                    lost.append(i)
                elif i not in raised:
                    raised.add(i)
                    errors.setdefault(i, []).append(f"{type(exc).__name__}: {exc}")
                    retries += 1
                    submit(i)
                else:
                    fail(i, f"{type(exc).__name__}: {exc}")
            if lost:
                # The pool is broken: whatever else was in it is lost too.
                lost += list(pending.values())
                pending.clear()
                engine.restart()
                ran_alone = len(lost) == 1 and lost[0] in lost_once
                for i in sorted(set(lost)):
                    if ran_alone:
                        fail(i, "its worker process died (run alone)")
                    elif i in lost_once:
                        alone.append(i)
                    else:
                        lost_once.add(i)
                        errors.setdefault(i, []).append("its worker process died")
                        retries += 1
                        submit(i)
    except BaseException:
        engine.cancel()
        raise
    finally:
        engine.bind(None)
    return results, failures, retries, errors

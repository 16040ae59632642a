"""Worker processes and threads: the one place where mcz spreads work over the cores `-j` gives.

Workers are forked, so they inherit what the parent holds when the pool starts (clips kept
in memory, an opened archive, what a module put in its `worker_state` for them) instead of
receiving it pickled: only each item and its result cross between processes. Inside a
`kept_workers` block (the encoder's classes) one pool serves every map, and each map's
`worker_state`, small there, is pickled to its workers once. Where fork is
not available, or one job is asked for, the work runs in the calling process, one item after
the other, exactly as the workers would do it. Inside `mocapzip.cluster.on_cluster`, the maps
go to a Dask cluster's workers instead, each item a task.

What a run in workers keeps from a run in one process: results in item order, the first
failing item's exception (at its turn, not before the results ahead of it), and the warnings
each item raised, given in the parent at the item's turn. What it adds: workers never
outlive the parent, and a Ctrl-C or a `kill` of the parent's process group is the parent's
to handle (one message, its clean-up), not every worker's.

Lossy decoding runs on threads instead (`thread_imap`): its time is spent in compiled code that
releases the GIL (numba kernels with nogil, numpy, scipy's DCT; h5py reads one at a time, but
they are small), and its results, whole files, would otherwise be pickled from worker to parent.

mcz's work runs on one BLAS thread per process (`one_blas_thread`): its matrices are small,
and it gets its parallelism from worker processes (or threads), one per core.
"""

from __future__ import annotations

import functools
import itertools
import multiprocessing
import os
import pickle
import shutil
import signal
import tempfile
import threading
import time
import traceback
import warnings
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor, wait
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

from mocapzip.defaults import BLAS_THREAD_VARIABLES


def one_blas_thread(function: Callable) -> Callable:
    """`function`, run with one BLAS thread (its workers fork with that limit) unless the
    environment sets a BLAS thread count: then that wins. The command line sets one before numpy
    loads (`mocapzip.cli`); this gives it to callers of the Python API, whose numpy starts a
    thread per core: `mocapzip.compress` of the shared CMU set with `jobs=2` took 72 s without
    it, against the command's 14.5 s, and cmu/07 with `jobs=1` 3x as long."""

    @functools.wraps(function)
    def limited(*args, **kwargs):
        if any(name in os.environ for name in BLAS_THREAD_VARIABLES):
            return function(*args, **kwargs)
        with threadpool_limits(limits=1):
            return function(*args, **kwargs)

    return limited


def use_one_blas_thread() -> None:
    """From now on, this process's BLAS runs on one thread, unless the environment sets a count
    (`one_blas_thread`'s rule, for processes that run tasks: a Dask worker)."""
    if not any(name in os.environ for name in BLAS_THREAD_VARIABLES):
        threadpool_limits(limits=1)


_CLUSTER: list = []  # the Dask cluster `parallel_map` and `imap` send their items to (`mocapzip.cluster`)
_STATES: dict[str, dict] = {}  # name -> the state workers read (`worker_state`)
_SHIPPED: list[str] = []  # the states a cluster's tasks need besides their module's (`worker_state(shipped=True)`)


def on_a_cluster() -> bool:
    """Whether maps go to a Dask cluster (`mocapzip.cluster.on_cluster`)."""
    return bool(_CLUSTER)


def worker_state(name: str, shipped: bool = False) -> dict:
    """The dict that the workers of maps of module `name`'s functions read, filled by this process
    before it maps: forked workers inherit it, `kept_workers`' get it pickled once per map, a Dask
    worker with each map (`map_state`). `shipped`: a state every map on a cluster takes besides its
    module's, which forked workers would have inherited (a loader that a module's state refers to)."""
    state = _STATES.setdefault(name, {})
    if shipped and name not in _SHIPPED:
        _SHIPPED.append(name)
    return state


def map_state(function: Callable) -> dict[str, dict]:
    """The states a map of `function` takes to a worker that did not fork from here: its module's
    and every shipped one, as copies."""
    return {name: dict(worker_state(name)) for name in dict.fromkeys([function.__module__, *_SHIPPED])}


def install_state(states: dict[str, dict]) -> list[dict]:
    """In a worker: each state's values as `map_state` took them; the dicts that now hold them."""
    installed = []
    for name, values in states.items():
        target = worker_state(name)
        target.clear()
        target.update(values)
        installed.append(target)
    return installed


_RUN_HERE: set = set()  # functions this process has run before forking workers for them (`parallel_map`)


def parallel_map(function: Callable, items, jobs: int) -> list:
    """`[function(item) for item in items]`, in `jobs` forked processes when that can help.

    The first time a function is mapped, its first item runs here, before the fork: numba then
    loads the compiled kernels it uses once, and the workers of every later pool have them (each
    would otherwise load them again from the cache, about a second per worker and pool). Inside
    `kept_workers`, the block's workers do the work; they fork at its first map, so kernels first
    used by a later function load once in each of them.
    """
    items = list(items)
    if _CLUSTER:
        return _CLUSTER[-1].map(function, items)
    done = []
    if jobs > 1 and len(items) > 1 and function not in _RUN_HERE:
        _RUN_HERE.add(function)
        done, items = [function(items[0])], items[1:]
    if _KEPT and jobs > 1 and len(items) > 1:
        return done + _KEPT[-1].map(function, items)
    return done + list(imap(function, items, jobs))


_KEPT: list = []  # the workers of the innermost `kept_workers` block, if any


@contextmanager
def kept_workers(jobs: int):
    """Within the block, `parallel_map` hands its items to one set of `jobs` forked workers, kept
    from map to map, instead of forking a pool for each map.

    A run that maps many times (the encoder: three maps per class) otherwise pays each pool's fork
    and shutdown, and each new worker's page faults as it warms a fresh heap: on the shared CMU
    set, 33 pools. The workers fork at the block's first map, so they inherit what the process
    holds then (clips kept in memory). What changes from map to map, the mapped function's module's
    `worker_state`, reaches them pickled, through a file each worker reads once per map: it must pickle
    small (clips indexed through a module-level loader, never held in it)."""
    if jobs <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        yield
        return
    kept = _Kept(jobs)
    _KEPT.append(kept)
    try:
        yield
    finally:
        _KEPT.pop()
        kept.close()


class _Kept:
    """`kept_workers`' pool, and the folder of the state files its maps send."""

    def __init__(self, jobs: int):
        self.jobs, self.pool, self.maps = jobs, None, 0
        self.others = set(multiprocessing.active_children())
        self.folder = tempfile.mkdtemp(prefix="mcz-shared-")

    def map(self, function: Callable, items: list) -> list:
        """`[function(item) for item in items]` in the kept workers, with `imap`'s warnings and first error."""
        module = function.__module__
        self.maps += 1
        state = os.path.join(self.folder, f"{self.maps}.pickle")
        with open(state, "wb") as file:
            pickle.dump(worker_state(module), file, protocol=pickle.HIGHEST_PROTOCOL)
        if self.pool is None:
            self.pool = ProcessPoolExecutor(self.jobs, mp_context=multiprocessing.get_context("fork"),
                                            initializer=_worker_start, initargs=(os.getpid(),))
        futures = [self.pool.submit(_call_with_state, module, state, function, item) for item in items]
        try:
            return [_result(future) for future in futures]
        finally:  # nothing of this map left running behind it
            for future in futures:
                future.cancel()
            wait(futures)
            os.remove(state)

    def close(self) -> None:
        if self.pool is not None:
            _shut(self.pool, self.others)
        shutil.rmtree(self.folder, ignore_errors=True)


_INSTALLED: dict = {}  # in a kept worker: module name -> the state file last put in its `worker_state`


def _call_with_state(module: str, state: str, function: Callable, item):
    """In a kept worker: the map's `worker_state` installed (read once per map), then `call`."""
    if _INSTALLED.get(module) != state:
        with open(state, "rb") as file:
            install_state({module: pickle.load(file)})
        _INSTALLED[module] = state
    return call(function, item)


def imap(function: Callable, items: Sequence, jobs: int, window: int | None = None,
         priorities: Sequence | None = None) -> Iterator:
    """`function(item)` for each of `items`, yielded in order, computed in `jobs` forked worker
    processes when that can help (else here, one at a time, as each is asked for).

    At most `window` items (default: all) are in flight, handed to workers but not yet
    yielded, so large results (decoded files) are never all held at once. An item whose
    function raised raises here, at its turn. When the iteration stops early (that error, an
    error of the consumer, Ctrl-C), the items not started are cancelled and the workers finish
    the few they hold (at most `jobs` + 1) before the exception goes on: no work is left
    running behind. A consumer that may stop early must close the generator
    (`contextlib.closing`), so that this happens at once rather than when it is collected.
    """
    if _CLUSTER:  # `priorities`: which items a cluster starts first (local workers take them in order)
        yield from _CLUSTER[-1].imap(function, items, window, priorities)
        return
    if jobs <= 1 or len(items) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        for item in items:
            yield function(item)
        return
    others = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(min(jobs, len(items)), mp_context=multiprocessing.get_context("fork"),
                               initializer=_worker_start, initargs=(os.getpid(),))
    try:
        yield from _in_order(lambda item: pool.submit(call, function, item), _result, items,
                             len(items) if window is None else window)
    finally:
        _shut(pool, others)


def thread_imap(function: Callable, items: Sequence, jobs: int, window: int) -> Iterator:
    """`function(item)` for each of `items`, yielded in order, computed by `jobs` threads of this
    process (or here, one at a time, for one job). For work whose time is spent outside the GIL:
    decoding (`Archive.made_files`). At most `window` items are in flight. An item that raised
    raises here, at its turn; when the iteration stops early, the items not started are cancelled
    and the running ones (at most `jobs`) finish first. Warnings are shown as each item raises
    them, not at its turn."""
    if jobs <= 1 or len(items) < 2:
        for item in items:
            yield function(item)
        return
    pool = ThreadPoolExecutor(min(jobs, len(items)), thread_name_prefix="mcz-decode")
    try:
        yield from _in_order(lambda item: pool.submit(function, item), Future.result, items, window)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _in_order(start: Callable, outcome: Callable, items: Sequence, window: int) -> Iterator:
    """`outcome(start(item))` for each of `items` (`start` hands it to a pool: a future), in item
    order, with at most `window` started and not yet yielded; when the iteration stops, those
    not yet yielded are cancelled (the running ones cannot be: the caller's pool waits for them)."""
    pending: deque = deque()
    queue = iter(items)
    try:
        def submit() -> None:
            for item in itertools.islice(queue, max(1, window) - len(pending)):
                pending.append(start(item))

        submit()
        while pending:
            result = outcome(pending.popleft())
            submit()
            yield result
    finally:
        for future in pending:
            future.cancel()


def _result(future):
    """A worker's result, its warnings given here first (as one process raises them, at the item's
    turn), or the exception it raised, with the worker's traceback as its cause."""
    return _unpacked(future.result())


def _unpacked(outcome: tuple):
    """What `call` returned in a worker, as `_result` gives it."""
    caught, result, error = outcome
    for message, category, filename, lineno in caught:
        warnings.warn_explicit(message, category, filename, lineno)
    if error is not None:
        raise error[0] from _RemoteTraceback(error[1])
    return result


def _shut(pool: ProcessPoolExecutor, others: set) -> None:
    """Stop `pool`: the items not started cancelled, the running ones finished. A pool that failed
    to start all its workers (fork refused: EAGAIN, ENOMEM) has no thread to stop those it
    started, and the interpreter would wait for them at exit forever: every child not among
    `others` (those before the pool) is killed. They hold nothing to clean up; one may not yet
    have left the parent's SIGTERM handler."""
    pool.shutdown(wait=True, cancel_futures=True)
    for process in set(multiprocessing.active_children()) - others:
        process.kill()
        process.join()


def call(function: Callable, item) -> tuple[list, object, tuple[BaseException, str] | None]:
    """What a worker runs of an item (here, or a cluster's: `mocapzip.cluster`): (warnings raised,
    result, None) or (warnings raised, None, (exception, its traceback)).
    The warnings travel back even when the item fails, as they would have been shown before the error."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result, error = function(item), None
        except Exception as exc:
            result, error = None, (exc, traceback.format_exc())
    return [(w.message, w.category, w.filename, w.lineno) for w in caught], result, error


class _RemoteTraceback(Exception):
    """Where a worker's exception came from (its traceback, as text): the cause of the exception re-raised."""

    def __str__(self) -> str:
        return f"\n\"\"\"\n{self.args[0]}\"\"\""


def _worker_start(parent: int) -> None:
    """Worker start-up. Ctrl-C in a terminal reaches the whole process group: the workers ignore
    it and the parent, which handles it, stops them (`imap`); a SIGTERM ends a worker at once
    (its inherited handler would raise KeyboardInterrupt and print a traceback). Then the watch
    for a parent gone without clean-up (`_exit_with_parent`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _exit_with_parent(parent)


def _exit_with_parent(parent: int) -> None:
    """A watcher thread ends the worker once its parent is gone. A parent killed by SIGKILL
    runs no clean-up, and its workers would otherwise wait for work forever."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()

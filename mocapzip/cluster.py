"""`mcz compress --dask ADDRESS`: the work `mocapzip.parallel` maps, run as tasks on a Dask cluster.

Inside `on_cluster`, every `parallel_map` and `imap` of the process goes to the cluster's
workers instead of forked ones: the first pass's reading (a task per clip, which sends back only
what the client keeps of it: `first_pass._read_and_take`), the class coding (a task per class:
`class_coding._class_task`) and the priors' re-coding (a task per clip: `priors._primed_stream`). The
client (this process) does everything else, in the same order as with local workers, and writes
the archive. Each task computes what local workers would from the same item and the same state,
so the archive is byte-identical to `-j N`'s.

A task's state is what a forked worker would have inherited: its function's module's
`parallel.worker_state`, and the states shipped with every map (the encoder's clip loader). It is pickled once
per map, sent as a task's argument (`Cluster._state`), fetched by each worker and installed there
before its first task of the map, with the client's working folder as the worker's; a worker
process runs one task at a time. Clips
are not in it (except -c auto's, which compares every clip's poses): workers read them again from
the paths the client found, so the data must be on storage the workers share with the client, at
the same paths. A `ClipReader` pickles without the clips it keeps (`ClipReader.__getstate__`).

Dask itself recovers from a lost worker: the scheduler gives its tasks to the others, and makes
the state again if that worker held it. A task that keeps killing its workers
(Dask's `allowed-failures`), a task Dask cannot run (a worker with another mcz), or a cluster that
goes away ends the run with `ClusterError`; an item's own error ends it as with local workers.
"""

from __future__ import annotations

import gc
import logging
import os
import pickle
import re
import signal
import socket
import struct
import sys
import threading
import time
import uuid
from collections import deque
from contextlib import contextmanager

from mocapzip import parallel
from mocapzip.defaults import BLAS_THREAD_VARIABLES
from mocapzip.progress import progress

# Dask's nannies start workers with MALLOC_TRIM_THRESHOLD_ set, which turns off glibc's adaptive mmap
# threshold: every large numpy array is then mapped and unmapped afresh. mcz's tasks ran 1.7x slower
# so (system time 11 s against 3 s, shared CMU set, one local worker). docs/cluster.md says how to
# start remote workers without it.
LOCAL_WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
CONNECT_TIMEOUT_S = 20  # to reach a scheduler given by address and have its handshake, however the peer behaves
# `local:N`: at most this many worker processes per core of this machine. A task is CPU-bound and a worker
# runs one at a time, so more gain nothing; each costs its process, and this process's address space grows
# by about 0.2 GB a worker (glibc's arena of each nanny's thread): 0.96 GB at local:1, 1.66 GB at local:8.
LOCAL_WORKERS_PER_CORE = 1
# A run's tasks may go this long with none finished before mcz asks the scheduler whether a worker is
# running one; a scheduler that does not answer, or has none running, ends the run (a peer that took the
# tasks and never ran them hung it for ever). Dask's config `mcz.stall-timeout` sets it (docs/cluster.md).
STALL_TIMEOUT_S = 300
HANDSHAKE_MAX_BYTES = 1 << 16  # a scheduler's first message, its handshake, takes about 60 bytes
SMALLEST_WINDOW_PER_WORKER = 4  # imap's items in flight per worker, at least: enough to keep each one busy
ONE_LINE_CHARS = 200  # of an error's message that Dask raised, in mcz's one line


class ClusterError(Exception):
    """The cluster could not be used, or it lost work it could not redo: one line, no archive written."""


def parse_address(address: str) -> tuple[int | None, str | None]:
    """(N, None) for `local` (N: the cores) or `local:N`; (None, address) for a scheduler's address.
    N is capped: each worker is a process, and `local:100000` would try to start them all."""
    if address == "local" or address.startswith("local:"):
        cores = os.cpu_count() or 1
        count = address.partition(":")[2] or str(cores)
        most = LOCAL_WORKERS_PER_CORE * cores
        if not (count.isascii() and count.isdigit() and len(count) <= 9) or not 1 <= int(count) <= most:
            raise ClusterError(f"--dask {address[:40]}: expected local or local:N with N a number of workers from 1 to "
                               f"{most} ({LOCAL_WORKERS_PER_CORE} per core of this machine's {cores})")
        return int(count), None
    if not address or any(c.isspace() for c in address):
        raise ClusterError(f"--dask {address[:60]!r}: expected a scheduler address such as tcp://host:8786, or local:N")
    port = re.search(r":(-?\d+)/?$", address)
    if port and not (len(port[1]) <= 6 and 1 <= int(port[1]) <= 65535):  # 70000 would reach port 4464
        raise ClusterError(f"--dask {address[:60]}: port {port[1][:10]} is not a port (1 to 65535)")
    return None, address


@contextmanager
def on_cluster(address: str, dashboard: bool = False):
    """Within the block, `parallel` maps run on the Dask cluster at `address` (`parse_address`):
    a scheduler already running, or a `LocalCluster` of N worker processes started here (and
    stopped after; its dashboard on this machine only). Yields the `Cluster`. Dask's own log
    lines are silenced meanwhile: what goes wrong ends the run with one line (`ClusterError`)."""
    workers, scheduler = parse_address(address)
    handshaken = False  # the peer answered a Dask handshake (tcp:// alone is checked): it may still answer wrongly
    try:
        import dask
        import distributed
    except ImportError:
        raise ClusterError("--dask needs Dask's distributed scheduler: pip install 'mocapzip[dask]'") from None
    if scheduler is not None:
        # Checked before a Client is made: one that fails while it is made is collected later, and its
        # clean-up can deadlock another's start. Dask's own connect waits for the handshake without a deadline.
        try:
            host, port = distributed.comm.get_address_host_port(scheduler)
        except ValueError as exc:
            raise ClusterError(f"the Dask scheduler at {scheduler} cannot be reached ({exc})") from None
        if distributed.comm.parse_address(scheduler)[0] == "tcp":
            _check_handshake(scheduler, host, port, CONNECT_TIMEOUT_S)
            handshaken = True
    with _blas_variables_kept(), _dask_logs_quiet():
        local = client = None
        try:
            if workers is not None:
                with dask.config.set(LOCAL_WORKER_CONFIG), _children_ignore_ctrl_c(), _blas_variables_kept():
                    local = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                                     dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
                scheduler = local.scheduler_address
            client = distributed.Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s", set_as_default=False)
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except Exception as exc:  # Dask raises whatever the peer's answers make it: any type, even the peer's own
            for opened in (client, local):
                if opened is not None:
                    opened.close()
            what = "has no workers" if client is not None else "cannot be reached"
            message = f"the Dask scheduler at {scheduler} {what} ({_one_line(exc)})"
            if workers is not None and local is None:  # its scheduler or a worker's process did not start
                message = f"--dask {address}: the local cluster could not start ({_one_line(exc)})"
            elif isinstance(exc, MemoryError):  # Dask read a size from the peer's bytes: not Dask's messages
                message = (f"--dask {scheduler}: not a Dask scheduler (after its handshake, bytes Dask read as "
                           "a message size past memory)")
            elif handshaken and not isinstance(exc, (OSError, TimeoutError)):  # answers no scheduler gives
                message = (f"--dask {scheduler}: not a Dask scheduler (after its handshake, Dask read its answers "
                           f"as {_one_line(exc)})")
            del exc
            gc.collect()  # a Client that failed while it was made is closed now, not during the next one's start
            raise ClusterError(message) from None
        run = Cluster(client, local is not None)
        parallel._CLUSTER.append(run)
        try:
            yield run
            if local is None:  # a scheduler that outlives this run: its workers forget this run's state
                try:
                    client.run(_forget, run.state_ids, on_error="ignore")
                except Exception:  # the archive is written: a worker gone by now changes nothing
                    pass
        finally:  # after an error or Ctrl-C, at once (a dead worker would hold up `client.run` for 30 s)
            parallel._CLUSTER.pop()
            run.bar.close()
            client.close()
            if local is not None:
                local.close()


def _check_handshake(address: str, host: str, port: int, timeout: float) -> None:
    """The peer at a tcp:// `address` answers a Dask handshake within `timeout` seconds from the
    start of the connection, else `ClusterError`. Dask's own connect waits for that answer without
    a deadline, and allocates what the answer's first 8 bytes declare: a port that never answers
    hung the run, and one that answered HTTP asked for 3 EiB. Each size of the answer is checked
    here before it is read. A peer refused or out of reach is tried again until the deadline, as
    Dask does (a scheduler may be starting)."""
    import msgpack  # a dependency of distributed

    deadline = time.monotonic() + timeout
    while True:
        try:
            connection = socket.create_connection((host, port), timeout=max(deadline - time.monotonic(), 0.001))
            break
        except UnicodeError as exc:  # a host name IDNA cannot encode ("a..b", a label over 63 characters)
            raise ClusterError(f"the Dask scheduler at {address[:80]} cannot be reached (host name: {exc})") from None
        except OSError as exc:
            if time.monotonic() + 0.1 >= deadline:
                raise ClusterError(f"the Dask scheduler at {address} cannot be reached "
                                   f"({type(exc).__name__}: {exc.strerror or exc})") from None
            time.sleep(0.1)
    info = msgpack.packb({"compression": None, "python": tuple(sys.version_info)[:3],
                          "pickle-protocol": pickle.HIGHEST_PROTOCOL})  # as Dask's `Comm.handshake_info`
    received = bytearray()
    try:
        with connection:
            connection.settimeout(max(deadline - time.monotonic(), 0.001))
            # Ours first: a scheduler then drops the connection quietly when it closes (else Dask logs it).
            connection.sendall(struct.pack("3Q", 16 + len(info), 1, len(info)) + info)
            _receive(connection, received, 8, deadline)
            (size,) = struct.unpack("Q", received)
            if not 16 <= size <= HANDSHAKE_MAX_BYTES:  # the bytes tell what answered: b'HTTP/1.1', b'SSH-2.0-'
                raise ValueError(f"its answer begins {bytes(received)!r}, read as a first message of {size:,} bytes")
            _receive(connection, received, 8 + size, deadline)
        _handshake(bytes(received[8:]))
    except TimeoutError:
        why = f"it sent {len(received)} bytes of a handshake within {timeout:g} s"
    except (ConnectionError, EOFError):
        why = f"it closed the connection after {len(received)} bytes of a handshake"
    except OSError as exc:
        why = f"{exc.strerror or exc} after {len(received)} bytes of a handshake"
    except ValueError as exc:
        why = str(exc)
    else:
        return
    raise ClusterError(f"--dask {address}: not a Dask scheduler ({why})")


def _one_line(exc: BaseException) -> str:
    """`Type: message`, the message's first line and at most ONE_LINE_CHARS of it: a peer's answer
    decides what Dask raises, and with what text."""
    text = str(exc).strip().split("\n")[0]
    return f"{type(exc).__name__}: {text[:ONE_LINE_CHARS]}{'...' if len(text) > ONE_LINE_CHARS else ''}"


def _receive(connection: socket.socket, received: bytearray, size: int, deadline: float) -> None:
    """`received` filled up to `size` bytes from `connection` by `deadline` (TimeoutError), or
    EOFError if the peer closes first."""
    while len(received) < size:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        connection.settimeout(left)
        chunk = connection.recv(size - len(received))
        if not chunk:
            raise EOFError
        received += chunk


def _handshake(message: bytes) -> dict:
    """The handshake a Dask message holds (as `distributed.comm.tcp` writes it, in native byte
    order: a frame count, each frame's size, the frames; the first frame msgpack), each size
    checked against the message before it is used; ValueError saying what is wrong."""
    import msgpack  # a dependency of distributed

    (frames,) = struct.unpack_from("Q", message)
    if not 1 <= frames <= len(message) // 8 - 1:
        raise ValueError(f"it declares {frames:,} frames in {len(message):,} bytes")
    sizes = struct.unpack_from(f"{frames}Q", message, 8)
    start = 8 * (1 + frames)
    if sum(sizes) != len(message) - start:
        raise ValueError(f"its frames' sizes add up to {sum(sizes):,} bytes, not the {len(message) - start:,} sent")
    try:
        handshake = msgpack.unpackb(message[start:start + sizes[0]])
    except (ValueError, msgpack.UnpackException) as exc:
        raise ValueError(f"its first frame is not msgpack ({type(exc).__name__})") from None
    if not isinstance(handshake, dict) or not isinstance(handshake.get("pickle-protocol"), int):
        raise ValueError("its first frame is not a Dask handshake")
    return handshake


@contextmanager
def _dask_logs_quiet():
    """Dask's loggers above CRITICAL for the block: a lost scheduler otherwise prints its traceback,
    and so does a message Dask cannot decode, at CRITICAL (Dask sets some of its loggers' levels
    itself, so each is set, not only their parent)."""
    names = [name for name in logging.root.manager.loggerDict if name.split(".")[0] == "distributed"]
    loggers = [logging.getLogger(name) for name in ["distributed", *names]]
    previous = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for logger, level in zip(loggers, previous):
            logger.setLevel(level)


@contextmanager
def _blas_variables_kept():
    """This process's BLAS thread variables as they were before the block (the cluster's start, and
    the whole run: a nanny that restarts a worker sets them again). Each local worker a nanny starts
    sets them to 1 here; numpy's BLAS, already loaded, would keep its threads,
    while `parallel.one_blas_thread` took the variables for the user's choice and stopped limiting
    them: a later `compress` in this process wrote another archive than the command line's."""
    before = {name: os.environ.get(name) for name in BLAS_THREAD_VARIABLES}
    try:
        yield
    finally:
        for name, value in before.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextmanager
def _children_ignore_ctrl_c():
    """Worker processes started in the block ignore SIGINT (a process started with it ignored keeps
    ignoring it, in Python and asyncio alike). Ctrl-C in a terminal reaches the whole process
    group: mcz handles it (one line, the cluster closed, no file left), and the workers would
    otherwise each print a traceback. A worker a nanny restarts later does not inherit this."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class Cluster:
    """A connected Dask client that runs `parallel`'s maps as tasks, and the progress bar of its tasks."""

    def __init__(self, client, local: bool):
        self.client, self.local = client, local
        self.bar = progress(total=0, desc="cluster", unit="task")
        self.submitted = self.done = 0  # tasks sent to the cluster, and those it has finished
        self.state_ids: set[str] = set()  # of this run's maps (`_forget`)
        self._lock = threading.Lock()

    @property
    def workers(self) -> int:
        """Worker processes the scheduler has now (each runs one mcz task at a time); ClusterError
        if it does not say within CONNECT_TIMEOUT_S (Dask itself would wait for ever)."""
        try:
            return max(1, len(self.client.nthreads(callback_timeout=CONNECT_TIMEOUT_S)))
        except Exception as exc:  # a peer that stopped answering, or answers what no scheduler does
            raise ClusterError(f"the Dask scheduler at {self.client.scheduler.address} did not say how many workers "
                               f"it has ({_one_line(exc)})") from None

    def describe(self) -> str:
        """One line for `-v`: where the work runs, and the dashboard if there is one."""
        kind = "a local cluster" if self.local else "the scheduler"
        link = self.client.dashboard_link if self.client.scheduler_info().get("services", {}).get("dashboard") else None
        return (f"dask: {kind} at {self.client.scheduler.address}, {self.workers} workers; "
                + (f"dashboard {link}" if link else "no dashboard (pip install bokeh, or start the scheduler with one)"))

    def map(self, function, items: list) -> list:
        """`[function(item) for item in items]` on the cluster, with `parallel.imap`'s warnings and first error."""
        return list(self.imap(function, items))

    def imap(self, function, items, window: int | None = None, priorities: list | None = None):
        """`function(item)` of each item, yielded in order; at most `window` in flight (at least
        SMALLEST_WINDOW_PER_WORKER per worker), started in item order or, given `priorities`, the
        highest first. Stopping early cancels the tasks not yet yielded."""
        items = list(items)
        if not items:
            return
        window = len(items) if window is None else max(window, SMALLEST_WINDOW_PER_WORKER * self.workers)
        state, state_id = self._state(function)
        pending: deque = deque()
        queue = iter(enumerate(items))

        def submit() -> None:
            for i, item in queue:
                future = self.client.submit(_task, state_id, state, function, item, pure=False,
                                            key=f"{function.__name__}-{state_id}-{i}",
                                            priority=-i if priorities is None else priorities[i])
                future.add_done_callback(self._done)
                pending.append(future)
                with self._lock:
                    self.submitted += 1
                    self.bar.total = self.submitted
                if len(pending) >= window:
                    return

        try:
            submit()
            while pending:
                outcome = self._outcome(pending.popleft())
                submit()
                yield parallel._unpacked(outcome)
        finally:
            if pending:
                self.client.cancel(list(pending))

    def _state(self, function):
        """The map's state, pickled, as a task that returns it: the scheduler holds the pickle, so it
        makes the state again if the worker holding it dies. (Scattered data cannot be made again, and
        Dask's memory manager keeps a single copy of it once no task waits for it.)"""
        blob = pickle.dumps((os.getcwd(), parallel.map_state(function)), protocol=pickle.HIGHEST_PROTOCOL)
        state_id = uuid.uuid4().hex[:12]
        self.state_ids.add(state_id)
        import dask  # here: Dask is an optional extra, and a Cluster exists only if it is installed
        from dask.utils import parse_bytes

        threshold = max(parse_bytes(dask.config.get("distributed.admin.large-graph-warning-threshold")),
                        len(blob) + (1 << 20))  # the state is meant to travel in the graph: no warning for it
        with dask.config.set({"distributed.admin.large-graph-warning-threshold": threshold}):
            return self.client.submit(_returned, blob, key=f"state-{state_id}", pure=False), state_id

    def _outcome(self, future):
        """The task's result, waiting as long as the cluster makes progress (`_check_progress`)."""
        try:
            while True:
                done = self.done
                try:
                    return future.result(timeout=self.stall_timeout)
                except TimeoutError:
                    if self.done == done:
                        self._check_progress()
        except ClusterError:
            raise
        except Exception as exc:  # the task's own errors come back as values (`parallel.call`): this is Dask's
            detail = str(exc).split(". ")[0].splitlines()[0] if str(exc) else "no detail"
            raise ClusterError(f"the Dask cluster could not run a task ({type(exc).__name__}: {detail})") from None

    @property
    def stall_timeout(self) -> float:
        """Seconds without a finished task before `_check_progress`: Dask's config `mcz.stall-timeout`
        (environment: DASK_MCZ__STALL_TIMEOUT), else STALL_TIMEOUT_S."""
        import dask
        from dask.utils import parse_timedelta

        given = dask.config.get("mcz.stall-timeout", STALL_TIMEOUT_S)
        try:
            seconds = parse_timedelta(given, default="seconds")
        except (TypeError, ValueError, KeyError):
            seconds = None
        if seconds is None or not 0 < seconds < 1e9:
            raise ClusterError(f"Dask's config mcz.stall-timeout: {str(given)[:40]!r} is not a time such as 300 or '5m'")
        return seconds

    def _check_progress(self) -> None:
        """ClusterError unless the scheduler says, within CONNECT_TIMEOUT_S, that a worker is running a
        task (this run's or another's: a shared scheduler may run others' first)."""
        address, waited = self.client.scheduler.address, f"{self.stall_timeout:g} s"
        try:
            processing = self.client.sync(self.client.scheduler.processing, workers=None,
                                          callback_timeout=CONNECT_TIMEOUT_S)
        except Exception as exc:  # a peer that stopped answering, or answers what no scheduler does
            raise ClusterError(f"the Dask scheduler at {address} finished no task in {waited} and did not say what "
                               f"its workers are doing ({_one_line(exc)})") from None
        if not isinstance(processing, dict) or not any(processing.values()):
            raise ClusterError(f"the Dask scheduler at {address} finished no task in {waited} and none is running "
                               "(mcz.stall-timeout, docs/cluster.md)")

    def _done(self, future) -> None:
        with self._lock:
            self.done += 1
            self.bar.update(1)


def _returned(blob: bytes) -> bytes:
    """In a worker: a map's pickled state, as the task `Cluster._state` submits."""
    return blob


_INSTALLED = {"id": None, "dicts": []}  # in a worker: the state its module dicts hold now, and those dicts
# One task at a time in a worker process, whatever its threads: a task's state lives in module dicts
# (and the encoder keeps its own in its module), which a task of another map, or of another run on
# the same scheduler, would replace under it.
_ONE_TASK_AT_A_TIME = threading.Lock()


def _task(state_id: str, state: bytes, function, item):
    """In a worker: the map's state installed (unless it is already), then `parallel.call`."""
    with _ONE_TASK_AT_A_TIME:
        if _INSTALLED["id"] != state_id:
            installed = parallel.call(lambda blob: _install(*pickle.loads(blob)), state)
            if installed[2] is not None:  # the item's error, given at its turn
                return installed
            _INSTALLED["id"] = state_id
        return parallel.call(function, item)


def _install(folder: str, state: dict) -> None:
    """The client's working folder (the paths it found clips by may be relative to it), and each
    dict's values as the client holds them."""
    try:
        os.chdir(folder)
    except OSError as exc:
        raise ClusterError(f"the folder mcz was run from, {folder}, is not on the Dask worker "
                           f"{os.uname().nodename} ({exc.strerror}): the workers must see the clips at the "
                           "same paths as this machine (docs/cluster.md)") from None
    parallel.use_one_blas_thread()
    for target in parallel.install_state(state):
        if not any(target is installed for installed in _INSTALLED["dicts"]):
            _INSTALLED["dicts"].append(target)


def _forget(state_ids: set) -> None:
    """In a worker: its module dicts cleared if they hold one of `state_ids` (a run's), not another run's."""
    with _ONE_TASK_AT_A_TIME:
        if _INSTALLED["id"] in state_ids:
            for target in _INSTALLED["dicts"]:
                target.clear()
            _INSTALLED.update(id=None, dicts=[])

"""`mcz compress --dask` at a peer that is not a Dask scheduler (issue 40): a port that never
answers, one that answers HTTP, one whose first bytes declare an enormous message, other
answers that are no Dask handshake, and a handshake followed by answers no scheduler gives, or
by silence. Each run ends within mcz's connect timeout (1 s in the child) with one line, exit
code 1 and no file. `--dask local:N` beyond the machine's cores is a usage error, and a local
cluster that cannot start is one line.

Each peer is a thread of the test listening on 127.0.0.1. Nothing depends on how fast anything
runs: a run that hangs meets the child's timeout (`tests/limited.py`) and fails its test.
"""

from __future__ import annotations

import os
import socket
import struct
import threading
from contextlib import contextmanager

import msgpack
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapzip import cluster

from limited import run_mcz

SHORT_TIMEOUT = "from mocapzip import cluster; cluster.CONNECT_TIMEOUT_S = 1"


def message(*frames: bytes, count: int | None = None, sizes: list[int] | None = None) -> bytes:
    """A Dask message as `distributed.comm.tcp` writes it (its size, frame count, frame sizes,
    frames), with the count or the sizes replaced where a case lies about them."""
    prelude = struct.pack(f"Q{len(frames)}Q", len(frames) if count is None else count,
                          *(sizes or [len(frame) for frame in frames]))
    body = prelude + b"".join(frames)
    return struct.pack("Q", len(body)) + body


HANDSHAKE = msgpack.packb({"compression": None, "python": [3, 11, 7], "pickle-protocol": 5})  # a scheduler's

# What each peer sends once the connection is open, and whether it then closes it (else it holds it open).
PEERS = {
    "silent": (b"", False),
    "http_400": (b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n", True),
    "size_of_an_exbibyte": (struct.pack("Q", 1 << 60), False),
    "size_of_a_gibibyte": (struct.pack("Q", 1 << 30), False),  # allocatable: Dask would then wait for it
    "size_too_small": (struct.pack("Q", 8) + bytes(8), False),
    "frame_count_lies": (message(HANDSHAKE, count=1 << 40), False),
    "frame_sizes_lie": (message(HANDSHAKE, sizes=[len(HANDSHAKE) + 1]), False),
    "not_msgpack": (message(b"\xc1" * 8), False),
    "msgpack_not_a_handshake": (message(msgpack.packb([1, 2, 3])), False),
    "handshake_without_pickle_protocol": (message(msgpack.packb({"compression": None})), False),
    "closes_at_once": (b"", True),
    "closes_mid_handshake": (message(HANDSHAKE)[:20], True),
    "trickles_forever": (None, False),  # a first message of 32 KiB, a byte every 0.1 s: never whole
    # a handshake that passes mcz's check, then what Dask's own connections read as a message's size
    "handshake_then_http": (message(HANDSHAKE) + b"HTTP/1.1 400 Bad Request" + bytes(1000), False),
    "handshake_then_an_exbibyte": (message(HANDSHAKE) + struct.pack("Q", 1 << 60), False),
    # a handshake, then an answer Dask raises on as no scheduler's: before, a traceback (AssertionError,
    # the peer's own exception re-raised, struct.error; msgpack's error after Dask's CRITICAL log line)
    "handshake_then_an_empty_dict": (message(HANDSHAKE) + message(msgpack.packb({})), False),
    "handshake_then_its_own_exception": (message(HANDSHAKE) + message(msgpack.packb(
        {"status": "uncaught-error", "exception": "x", "traceback": None, "text": "x"})), False),
    "handshake_then_a_frame_count_that_lies": (message(HANDSHAKE) + message(msgpack.packb({}), count=1 << 40), False),
    "handshake_then_no_msgpack": (message(HANDSHAKE) + message(b"\xc1" * 8), False),
}


# A scheduler's answers to the client's start (its identity, claiming a worker; the stream's start),
# and silence after them.
SILENT_AFTER_THE_START = {
    "identity": {"type": "Scheduler", "id": "s", "address": "tcp://127.0.0.1:1", "services": {}, "started": 0.0,
                 "workers": {"tcp://127.0.0.1:2": {"type": "Worker", "id": "w", "host": "127.0.0.1", "resources": {},
                                                   "local_directory": "/tmp", "name": "w", "nthreads": 1,
                                                   "memory_limit": 1 << 30, "last_seen": 0.0, "services": {},
                                                   "metrics": {}, "status": "running", "nanny": None}}},
    "register-client": [{"op": "stream-start"}]}


def answer_by_op(connection: socket.socket, replies: dict, stop: threading.Event) -> None:
    """A scheduler's handshake, then to each message received (after the client's handshake) the
    message `replies` holds for its op (a message's or a list's first), and silence for any other."""
    connection.sendall(message(HANDSHAKE))
    connection.settimeout(0.1)
    received, handshaken = b"", False
    while not stop.is_set():
        try:
            chunk = connection.recv(1 << 16)
        except TimeoutError:
            continue
        if not chunk:
            return
        received += chunk
        while len(received) >= 8 and len(received) >= 8 + struct.unpack_from("Q", received)[0]:
            size = struct.unpack_from("Q", received)[0]
            body, received = received[8:8 + size], received[8 + size:]
            if handshaken:
                (count,) = struct.unpack_from("Q", body)
                first = msgpack.unpackb(body[8 + 8 * count:8 + 8 * count + struct.unpack_from("Q", body, 8)[0]])
                op = (first[0] if isinstance(first, list) else first).get("op")
                if op in replies:
                    connection.sendall(message(msgpack.packb(replies[op])))
            handshaken = True


@contextmanager
def peer(answer: bytes | dict | None, close: bool):
    """A listener on 127.0.0.1 that sends `answer` on each connection it accepts (None: trickles a
    message that never ends; a dict: `answer_by_op`), then closes it or holds it open until the
    block ends. Yields its address."""
    listener = socket.create_server(("127.0.0.1", 0))
    held, stop = [], threading.Event()

    def serve(connection: socket.socket) -> None:
        try:
            if isinstance(answer, dict):
                answer_by_op(connection, answer, stop)
            elif answer is None:
                connection.sendall(struct.pack("Q", 1 << 15))
                while not stop.wait(0.1):
                    connection.sendall(b"\x00")
            else:
                connection.sendall(answer)
        except OSError:  # mcz gave up and closed its end
            pass
        if close:
            connection.close()

    def accept() -> None:
        while not stop.is_set():
            try:
                connection, _ = listener.accept()
            except OSError:  # the listener closed at the end of the block
                return
            held.append(connection)
            threading.Thread(target=serve, args=(connection,), daemon=True).start()

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        stop.set()
        listener.shutdown(socket.SHUT_RDWR)  # wakes the thread in accept(), which close() alone does not
        listener.close()
        for connection in held:
            connection.close()
        thread.join()


def compress_at(address: str, shared_data, tmp_path, setup: str = SHORT_TIMEOUT):
    """`mcz compress` of CMU subject 07 on the cluster at `address`, into an empty folder: (the run,
    what the folder holds after it)."""
    out = tmp_path / "out"
    out.mkdir()
    run = run_mcz("compress", shared_data / "cmu" / "07", "-o", out / "db.mcz", "--dask", address, "-q", setup=setup)
    return run, list(out.iterdir())


@pytest.mark.parametrize("case", PEERS)
def test_a_peer_that_is_not_a_scheduler_ends_the_run_in_one_line(shared_data, tmp_path, case):
    """Dask's connect waits for the handshake without a deadline and allocates the size its first
    8 bytes declare: a silent port hung the run, an HTTP answer asked for 3 EiB. mcz checks the
    handshake first, with a deadline: one line, exit code 1, nothing written."""
    with peer(*PEERS[case]) as address:
        run, written = compress_at(address, shared_data, tmp_path)
    assert run.returncode == 1, run.stderr
    assert run.stderr.startswith(f"mcz: error: --dask {address}: not a Dask scheduler ("), run.stderr
    assert len(run.stderr.splitlines()) == 1 and "Traceback" not in run.stderr, run.stderr
    assert run.stderr.rstrip().endswith("; no partial file was left behind")
    assert written == []


def test_a_scheduler_silent_after_the_start_ends_the_run_in_one_line(shared_data, tmp_path):
    """Before: a peer that answered the client's start, claiming a worker, and then nothing, hung
    the run for ever: Dask asks for the worker count without a deadline."""
    with peer(SILENT_AFTER_THE_START, False) as address:
        run, written = compress_at(address, shared_data, tmp_path)
    assert run.returncode == 1 and len(run.stderr.splitlines()) == 1, run.stderr
    assert run.stderr.startswith(f"mcz: error: the Dask scheduler at {address} did not say how many workers it has ("
                                 "TimeoutError: "), run.stderr
    assert written == []


def test_a_scheduler_that_never_runs_the_tasks_ends_the_run_in_one_line(shared_data, tmp_path, monkeypatch):
    """Before: a peer that answered the client's start and the worker count, took the tasks and
    never ran them, hung the run for ever. With no task finished within `mcz.stall-timeout` (Dask's
    config, here from the environment), mcz asks the scheduler what its workers run: this one does
    not answer."""
    monkeypatch.setenv("DASK_MCZ__STALL_TIMEOUT", "1")
    with peer({**SILENT_AFTER_THE_START, "ncores": {"tcp://127.0.0.1:2": 1}}, False) as address:
        run, written = compress_at(address, shared_data, tmp_path)
    assert run.returncode == 1 and len(run.stderr.splitlines()) == 1, run.stderr
    assert run.stderr.startswith(f"mcz: error: the Dask scheduler at {address} finished no task in 1 s and did not "
                                 "say what its workers are doing (TimeoutError"), run.stderr
    assert written == []


def test_a_scheduler_handshake_as_dask_writes_it_passes():
    """The check reads what Dask writes: a real handshake's message is taken, with its dict."""
    assert cluster._handshake(message(HANDSHAKE)[8:])["pickle-protocol"] == 5


@settings(max_examples=300, deadline=None)
@given(st.one_of(
    st.binary(min_size=16, max_size=200),  # any answer of a handshake's size
    st.binary(max_size=64).map(lambda frame: message(frame)[8:]),  # a message's layout, any first frame
    st.builds(lambda count, sizes, body: struct.pack(f"Q{len(sizes)}Q", count, *sizes) + body,  # a message's
              st.integers(0, 2**64 - 1), st.lists(st.integers(0, 2**64 - 1), min_size=1, max_size=4),  # layout
              st.binary(max_size=64)),  # whose count and sizes lie
))
def test_any_answer_is_a_handshake_or_a_value_error(answer):
    """Whatever the peer's message holds, the check gives a handshake or says what is wrong
    (`ValueError`, which `_check_handshake` makes one line): never another exception."""
    try:
        assert isinstance(cluster._handshake(answer), dict)
    except ValueError:
        pass


def test_local_workers_are_capped_at_the_cores():
    """`local:N` starts N worker processes: `local:100000` hung with no output, and `local:8` on 2
    cores took this process's address space to 1.66 GB for no speed (a task is CPU-bound)."""
    cores = os.cpu_count()
    assert cluster.parse_address(f"local:{cores}") == (cores, None)
    with pytest.raises(cluster.ClusterError, match=f"from 1 to {cores} "):
        cluster.parse_address(f"local:{cores + 1}")


def test_a_local_cluster_that_cannot_start_is_one_line(shared_data, tmp_path):
    """Before: a worker that failed to start (here: a preload that is not there) was reported as
    `--dask None: not a Dask scheduler`."""
    run, written = compress_at("local:1", shared_data, tmp_path,
                               setup="import dask; dask.config.set({'distributed.worker.preload': ['/nonexistent/x.py']})")
    assert run.returncode == 1 and len(run.stderr.splitlines()) == 1, run.stderr
    assert run.stderr.startswith("mcz: error: --dask local:1: the local cluster could not start (RuntimeError: "), \
        run.stderr
    assert written == []


@pytest.mark.parametrize("address", ["local:100000", "local:0", "tcp://a b", "local:" + "1" * 5000, "local:\uff11",
                                     "tcp://" + "a " * 3000])
def test_a_malformed_dask_address_is_a_usage_error(shared_data, tmp_path, address):
    """Refused before any work, as click refuses a bad option value: exit code 2, one error line."""
    run = run_mcz("compress", shared_data / "cmu" / "07", "-o", tmp_path / "db.mcz", "--dask", address)
    assert run.returncode == 2, run.stderr
    assert run.stderr.startswith("mcz compress: Invalid value for '--dask': "), run.stderr
    assert run.stderr.count("\n") == 1 and len(run.stderr) < 300
    assert list(tmp_path.iterdir()) == []


def test_a_scheme_whose_handshake_mcz_does_not_check_is_not_blamed_on_the_peer(shared_data, tmp_path):
    """Only tcp:// peers have their handshake checked. A tls:// address (no TLS configured here)
    was refused as "not a Dask scheduler (after its handshake, ...)": no handshake had been made,
    and the peer was not at fault."""
    out = tmp_path / "out"
    out.mkdir()
    with peer(*PEERS["silent"]) as address:
        tls = address.replace("tcp://", "tls://")
        run = run_mcz("compress", shared_data / "cmu" / "07", "-o", out / "db.mcz", "--dask", tls, "-q",
                      setup=SHORT_TIMEOUT)
    assert run.returncode == 1 and len(run.stderr.splitlines()) == 1, run.stderr
    assert run.stderr.startswith(f"mcz: error: the Dask scheduler at {tls} cannot be reached ("), run.stderr
    assert list(out.iterdir()) == []

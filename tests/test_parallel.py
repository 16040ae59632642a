"""Work on the cores `-j` gives (issue 15, deliverable 3): the first pass and the priors in worker
processes, decompress and `mcz test` on threads, give what one process gives (the same archive,
files, errors and warnings), hold only a few results at once, and stop cleanly on an error.

Behaviour only: nothing here depends on how fast anything runs.
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import threading
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from hostile_archives import BASES, Case, _stream, build
from mocapzip.archive import Archive, decompress
from mocapzip.codec.entropy.priors import stored_streams
from mocapzip.codec.clip_stream import CodedClip
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import ArchiveReader
from mocapzip.parallel import imap, kept_workers, parallel_map, thread_imap, worker_state
from mocapzip.progress import progress

GOLDEN = Path(__file__).parent / "golden"
MCZ = Path(sys.executable).with_name("mcz")
DEADLINE = 120.0  # seconds: only a hang reaches it


def mcz(*args) -> subprocess.CompletedProcess:
    return subprocess.run([MCZ, *map(os.fspath, args)], capture_output=True, text=True, timeout=DEADLINE)


def files_under(root: Path) -> dict[str, bytes]:
    """Every file under `root` (temporary ones included) and its bytes; {} if `root` does not exist."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


# --------------------------------------------------------------------------- the pool helper


def _square_with_a_warning(i: int) -> int:
    warnings.warn(f"item {i}")
    return i * i


def _fails_at_three(i: int) -> int:
    if i == 3:
        raise MocapFormatError(f"item {i} is bad", "some/file.amc", 7)
    return i


def _note_start(item: tuple[str, int]) -> int:
    folder, i = item
    Path(folder, str(i)).touch()
    return i


@pytest.mark.parametrize("jobs", [1, 2])
def test_results_and_warnings_come_in_item_order(jobs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = list(imap(_square_with_a_warning, range(12), jobs, window=3))
    assert results == [i * i for i in range(12)]
    assert [str(w.message) for w in caught] == [f"item {i}" for i in range(12)]
    assert parallel_map(abs, [-2, 1, -3], jobs) == [2, 1, 3]


def _nothing_left_running() -> bool:
    return multiprocessing.active_children() == [] and not any(
        thread.name.startswith("mcz-decode") for thread in threading.enumerate())


@pytest.mark.parametrize("jobs", [1, 2])
def test_threads_give_results_in_item_order(jobs):
    assert list(thread_imap(abs, range(-6, 6), jobs, window=3)) == [abs(i) for i in range(-6, 6)]
    assert _nothing_left_running()


@pytest.mark.parametrize("spread", [imap, thread_imap])
@pytest.mark.parametrize("jobs", [1, 2])
def test_a_failing_item_raises_at_its_turn_with_its_message(jobs, spread):
    got = []
    with pytest.raises(MocapFormatError) as failure:
        for result in spread(_fails_at_three, range(10), jobs, window=4):
            got.append(result)
    assert got == [0, 1, 2]  # the results before it, none after
    assert str(failure.value) == "some/file.amc:7: item 3 is bad"
    assert _nothing_left_running()  # no worker left behind


@pytest.mark.parametrize("spread", [imap, thread_imap])
def test_at_most_a_window_of_items_is_in_flight(tmp_path, spread):
    """However fast the workers are, no more than `window` items beyond those consumed are handed out."""
    window, items = 3, [(os.fspath(tmp_path), i) for i in range(20)]
    for consumed, result in enumerate(spread(_note_start, items, 2, window=window), start=1):
        assert result == consumed - 1
        assert len(os.listdir(tmp_path)) <= consumed + window
    assert len(os.listdir(tmp_path)) == len(items)


@pytest.mark.parametrize("spread", [imap, thread_imap])
def test_stopping_early_cancels_what_has_not_started(tmp_path, spread):
    window, items = 2, [(os.fspath(tmp_path), i) for i in range(50)]
    results = spread(_note_start, items, 2, window=window)
    assert [next(results), next(results)] == [0, 1]
    results.close()  # waits for the items the workers hold, cancels the others
    assert len(os.listdir(tmp_path)) <= 2 + window
    assert _nothing_left_running()


_SHARED = worker_state(__name__)  # what `kept_workers` sends the workers of the maps below


def _scaled(i: int) -> tuple[int, int]:
    """(the map's factor times i, the worker's pid), with a warning: the factor comes from `_SHARED`."""
    warnings.warn(f"item {i}")
    return _SHARED["factor"] * i, os.getpid()


def _scaled_or_failing(i: int) -> int:
    if i == _SHARED["bad"]:
        raise MocapFormatError(f"item {i} is bad", "some/file.amc", 7)
    return i


def test_kept_workers_serve_every_map_with_its_own_shared_state():
    """One set of workers for all the maps of a block, each map seeing the `_SHARED` it was made
    with; results and warnings in item order; nothing left running after the block."""
    pids = set()
    with kept_workers(2):
        for factor in (3, 5, 7):
            _SHARED["factor"] = factor
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                results = parallel_map(_scaled, range(9), 2)
            assert [value for value, _ in results] == [factor * i for i in range(9)]
            assert [str(w.message) for w in caught] == [f"item {i}" for i in range(9)]
            pids |= {pid for _, pid in results[1:]}  # the first item of the first map runs here
        assert len(multiprocessing.active_children()) == 2
    assert os.getpid() not in pids and len(pids) <= 2  # two workers served all three maps
    assert multiprocessing.active_children() == []
    _SHARED.clear()


def test_a_kept_worker_failure_raises_at_its_turn_and_the_block_ends_cleanly():
    with pytest.raises(MocapFormatError) as failure:
        with kept_workers(2):
            _SHARED["bad"] = 99
            assert parallel_map(_scaled_or_failing, range(8), 2) == list(range(8))
            _SHARED["bad"] = 4
            parallel_map(_scaled_or_failing, range(8), 2)
    assert str(failure.value) == "some/file.amc:7: item 4 is bad"
    assert multiprocessing.active_children() == []
    _SHARED.clear()


def test_progress_bars_start_no_thread_that_workers_would_fork_with():
    """Forking a process that runs a second thread risks a deadlock in the child (and Python 3.12 on
    warns of it on every fork): a progress bar, shown or not, starts no thread (tqdm's monitor)."""
    before = set(threading.enumerate())
    with progress(total=3, desc="test") as bar:
        bar.update()
        for _ in progress(range(3)):
            assert set(threading.enumerate()) <= before


# Runs the real `mcz` with its second fork refused (or every fork: FORKS_ALLOWED 0), as under a
# process limit (EAGAIN).
FORKS_REFUSED = r"""
import errno, os
from mocapzip.cli.main import main

real_fork, forks = os.fork, []

def fork():
    forks.append(None)
    if len(forks) > FORKS_ALLOWED:
        raise OSError(errno.EAGAIN, os.strerror(errno.EAGAIN))
    return real_fork()

os.fork = fork
main(prog_name="mcz")
"""


@pytest.mark.parametrize("command", ["compress", "decompress"])
def test_a_pool_that_cannot_start_all_its_workers_ends_the_run(tmp_path, shared_data, command):
    """One worker started, the second refused (compress; decompress of a lossless archive): one line,
    exit 1, no archive or file, and no wait for the first at exit."""
    out = tmp_path / "out"
    source = shared_data / "cmu" / "07" if command == "compress" else GOLDEN / "lossless_v4.mcz"
    result = subprocess.run([sys.executable, "-c", "FORKS_ALLOWED = 1\n" + FORKS_REFUSED, command, source,
                             "-o", out, "-j", "2", "-q"], capture_output=True, text=True, timeout=DEADLINE)
    assert result.returncode == 1
    assert result.stderr == "mcz: error: [Errno 11] Resource temporarily unavailable\n"
    assert list(tmp_path.iterdir()) == []


def test_decompress_and_test_of_a_lossy_archive_need_no_new_process(tmp_path):
    """Lossy clips decode on threads: under a limit that refuses every fork, -j 2 writes what -j 1
    writes. (A lossless archive's clips decode in worker processes: `Archive.made_files`.)"""
    archive = GOLDEN / "lossy_v4.mcz"
    out = tmp_path / "out"
    for command in (["decompress", archive, "-o", out, "-j", "2", "-q"], ["test", archive, "-j", "2", "-q"]):
        result = subprocess.run([sys.executable, "-c", "FORKS_ALLOWED = 0\n" + FORKS_REFUSED, *command],
                                capture_output=True, text=True, timeout=DEADLINE)
        assert (result.returncode, result.stderr) == (0, "")
    decompress(archive, tmp_path / "one", jobs=1)
    assert files_under(out) == files_under(tmp_path / "one") and len(files_under(out)) >= 3


# --------------------------------------------------------------------------- decompress and test


@pytest.mark.parametrize("golden", ["lossy_v4.mcz", "lossless_v4.mcz", "lossy_v1.mcz"])
def test_two_jobs_decompress_the_files_one_job_does(tmp_path, golden):
    archive = GOLDEN / golden
    one, two = tmp_path / "one", tmp_path / "two"
    assert decompress(archive, one, jobs=1) == {**decompress(archive, two, jobs=2), "output": os.fspath(one)}
    assert files_under(one) == files_under(two) and len(files_under(one)) >= 3
    assert mcz("test", archive, "-j", "2").returncode == 0


def test_a_skeleton_that_warns_warns_once_whatever_the_jobs(tmp_path, shared_data):
    """The stored ASF has a section mcz does not know, so reading it back warns. Decoding threads
    share the archive's skeletons: the warning comes once, and -j 1, 2 and 4 give the same
    messages and files."""
    clips = tmp_path / "clips"
    clips.mkdir()
    asf = (shared_data / "cmu" / "09" / "09.asf").read_text(encoding="latin-1")
    (clips / "09.asf").write_text(asf.replace("\n:name", "\n:namespace TEST\n:name", 1), encoding="latin-1")
    for name in ("09_02", "09_03", "09_08", "09_09"):
        shutil.copyfile(shared_data / "cmu" / "09" / f"{name}.amc", clips / f"{name}.amc")
    archive = tmp_path / "w.mcz"
    assert mcz("compress", clips, "-o", archive, "-j", "1", "-q").returncode == 0
    outcomes = {}
    for jobs in ("1", "2", "4"):
        result = mcz("decompress", archive, "-o", tmp_path / f"out{jobs}", "-j", jobs, "-q")
        outcomes[jobs] = (result.returncode, result.stderr, files_under(tmp_path / f"out{jobs}"))
    assert outcomes["1"] == outcomes["2"] == outcomes["4"]
    code, stderr, files = outcomes["1"]
    assert code == 0 and len(files) == 5
    assert stderr.count("mcz: warning:") == 1 and "namespace" in stderr, stderr


@pytest.mark.parametrize("base", ["lossless", "lossy"])  # decoded by worker processes, by threads
def test_a_clip_that_fails_to_decode_stops_two_jobs_as_it_stops_one(tmp_path, base):
    """The second of four files cannot be decoded (its checksum is right: only decoding finds it):
    with -j 2 and 4 as with -j 1, the same one-line error, the file before it written whole, no
    other file and no temporary file; `mcz test` reports it alike."""
    damaged = tmp_path / "damaged.mcz"
    build(Case("second_clip_3_bytes", base, _stream("clip/00001", b"abc"), "clip/00001"), damaged)
    outcomes = {}
    for jobs in ("1", "2", "4"):
        out = tmp_path / f"out{jobs}"
        result = mcz("decompress", damaged, "-o", out, "-j", jobs)
        tested = mcz("test", damaged, "-j", jobs)
        outcomes[jobs] = (result.returncode, result.stderr, files_under(out), tested.returncode, tested.stderr)
    assert outcomes["1"] == outcomes["2"] == outcomes["4"]
    code, stderr, written, test_code, test_stderr = outcomes["2"]
    assert code == test_code == 1
    assert stderr == test_stderr and len(stderr.splitlines()) == 1
    assert stderr.startswith(f"mcz: error: {damaged}: clip/00001 (64_01.amc): damaged")
    decompress(BASES[base], tmp_path / "whole", jobs=1)
    assert written == {"09_01.amc": (tmp_path / "whole" / "09_01.amc").read_bytes()}  # the first file, whole


def test_a_damaged_checksum_writes_nothing_with_two_jobs(tmp_path):
    data = bytearray((GOLDEN / "lossy_v4.mcz").read_bytes())
    with ArchiveReader(GOLDEN / "lossy_v4.mcz") as reader:
        payload = reader.read("clip/00001")
    start = data.find(payload)
    data[start + len(payload) // 2] ^= 0x55
    damaged = tmp_path / "d.mcz"
    damaged.write_bytes(bytes(data))
    result = mcz("decompress", damaged, "-o", tmp_path / "out", "-j", "2")
    assert result.returncode == 1
    assert result.stderr == f"mcz: error: {damaged}: stream 'clip/00001': CRC32 mismatch (clip 64_01.amc)\n"
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- compress


@pytest.fixture(scope="module")
def awkward_database(tmp_path_factory, shared_data) -> Path:
    """Real short clips with everything the first pass must handle in order: a skeleton that warns
    (an unknown section), shared by several clips; a clip that cannot be read; a clip cut in the
    middle of a frame (lossy: dropped frame, with a warning; lossless: skipped); a skeleton that
    cannot be read, shared by two clips; a second subject."""
    root = tmp_path_factory.mktemp("awkward")
    cmu = shared_data / "cmu"
    (root / "09").mkdir()
    (root / "35").mkdir()
    (root / "xx").mkdir()
    asf = (cmu / "09" / "09.asf").read_text(encoding="latin-1")
    (root / "09" / "09.asf").write_text(asf.replace("\n:name", "\n:namespace TEST\n:name", 1), encoding="latin-1")
    for name in ("09_02", "09_03", "09_08"):
        shutil.copyfile(cmu / "09" / f"{name}.amc", root / "09" / f"{name}.amc")
    lines = (cmu / "09" / "09_02.amc").read_text(encoding="latin-1").split("\n")
    lines[200] = "lowerback 1 2 x"
    (root / "09" / "09_bad.amc").write_text("\n".join(lines), encoding="latin-1")
    (root / "09" / "09_cut.amc").write_bytes((cmu / "09" / "09_03.amc").read_bytes()[:60_000])
    for name in ("35.asf", "35_21.amc"):
        shutil.copyfile(cmu / "35" / name, root / "35" / name)
    (root / "xx" / "xx.asf").write_text(":bogus\n")
    shutil.copyfile(cmu / "09" / "09_08.amc", root / "xx" / "a.amc")
    shutil.copyfile(cmu / "09" / "09_02.amc", root / "xx" / "b.amc")
    return root


@pytest.mark.parametrize("mode", [["--lossless"], pytest.param(["-e", "2"], marks=pytest.mark.slow)],
                         ids=["lossless", "lossy"])
def test_two_jobs_compress_the_archive_one_job_does(awkward_database, tmp_path, mode):
    """Same bytes, same skips, same warnings in the same order (each skeleton's once)."""
    runs = {}
    for jobs in ("1", "2"):
        path = tmp_path / f"j{jobs}.mcz"
        result = mcz("compress", awkward_database, "-o", path, "--skip-bad", "--json", "-j", jobs, *mode)
        assert result.returncode == 0, result.stderr
        runs[jobs] = (path.read_bytes(), result.stderr)
    assert runs["1"] == runs["2"]
    warned = runs["2"][1].splitlines()
    assert sum(":namespace" in line for line in warned) == 1
    assert [line.split(": ")[2] for line in warned if "skipped " in line and "ASF section" not in line] == (
        ["skipped 09/09_bad.amc"] + (["skipped 09/09_cut.amc"] if mode == ["--lossless"] else [])
        + ["skipped xx/a.amc", "skipped xx/b.amc"])


@pytest.mark.parametrize("coder", ["primed", "auto"])
def test_the_clips_coded_again_from_the_priors_in_workers_are_the_same(coder):
    """The streams as class coding holds them (coder "context"), made from a real archive's clips."""
    with Archive(GOLDEN / "lossy_v4.mcz") as archive, ArchiveReader(GOLDEN / "lossy_v4.mcz") as reader:
        interim = {name: CodedClip.from_payload(reader.read(name), "primed", None, archive.priors).payload("context")
                   for name in reader.names() if name.startswith("clip/")}
    assert len(interim) == 2
    one, two = stored_streams(interim, coder, jobs=1), stored_streams(interim, coder, jobs=2)
    assert one == two
    assert coder == "auto" or "priors" in one[1]

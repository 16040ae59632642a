"""`mcz compress --dask` (issue 20): the work as tasks on a Dask cluster gives the archive `-j 2`
gives, byte for byte; a worker killed mid-run changes nothing; a cluster that keeps losing the
work ends the run with one line and no output.

Every cluster here is a `distributed.LocalCluster` of worker processes on this machine. Nothing
depends on how fast anything runs.
"""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import dask
import pytest
from click.testing import CliRunner
from distributed import Client, LocalCluster
from distributed.diagnostics.plugin import WorkerPlugin

import mocapzip
from mocapzip.archive import writer
from mocapzip import cluster
from mocapzip.cli.main import main
from mocapzip.defaults import BLAS_THREAD_VARIABLES
from mocapzip.inputs.clip import ClipReader
from mocapzip.inputs.discover import find_clips

MCZ = Path(sys.executable).with_name("mcz")
DEADLINE = 600.0  # seconds: only a hang reaches it


def two_subjects(data: Path) -> list[Path]:
    """Two CMU subjects, two classes: short walks (07) and a mix (09)."""
    return [data / "cmu" / "07", data / "cmu" / "09"]


@pytest.fixture(scope="module")
def local_archive(shared_data, tmp_path_factory) -> bytes:
    """The two subjects' archive made by two local worker processes (`-j 2`)."""
    out = tmp_path_factory.mktemp("local") / "j2.mcz"
    mocapzip.compress(two_subjects(shared_data), out, jobs=2)
    return out.read_bytes()


def test_dask_local_2_writes_the_archive_of_j2(shared_data, tmp_path, local_archive):
    """The issue's proof, through the command line: `--dask local:2` starts a LocalCluster of two
    worker processes, and its archive is byte-identical to `-j 2`'s. `-v` names the cluster."""
    out = tmp_path / "dask.mcz"
    run = subprocess.run([MCZ, "compress", *two_subjects(shared_data), "-o", out, "--dask", "local:2",
                          "-v"], capture_output=True, text=True, timeout=DEADLINE)
    assert run.returncode == 0, run.stderr
    assert "mcz: dask: a local cluster at tcp://" in run.stderr and "2 workers" in run.stderr
    assert out.read_bytes() == local_archive


class _KillOnce(WorkerPlugin):
    """Kills the first worker that starts coding a class (`class_coding._class_task`) after `skip` such
    starts on it, once across the cluster (a file marks it done; with `every`, each time): the nanny
    restarts it, the scheduler hands its tasks on."""

    def __init__(self, marker: str, skip: int, prefix: str = "_class_task", every: bool = False):
        self.marker, self.skip, self.prefix, self.every, self.seen = marker, skip, prefix, every, 0

    def transition(self, key, start, finish, **kwargs):
        if finish != "executing" or not str(key).startswith(self.prefix):
            return
        self.seen += 1
        if self.seen <= self.skip:
            return
        if not self.every:
            try:
                os.close(os.open(self.marker, os.O_CREAT | os.O_EXCL))
            except FileExistsError:
                return
        os.kill(os.getpid(), signal.SIGKILL)


@pytest.fixture
def two_workers():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as local:
        yield local


def test_a_worker_killed_mid_run_changes_nothing(shared_data, tmp_path, local_archive, two_workers):
    """A worker dies (SIGKILL) as it starts coding a class: Dask gives its tasks to the other worker
    and to its restarted self, and the archive is still byte-identical to `-j 2`'s."""
    marker = tmp_path / "killed"
    with Client(two_workers) as client:
        client.register_plugin(_KillOnce(os.fspath(marker), skip=0))
        out = tmp_path / "dask.mcz"
        mocapzip.compress(two_subjects(shared_data), out, dask=two_workers.scheduler_address)
    assert marker.exists(), "no worker was killed: the test did not test anything"
    assert out.read_bytes() == local_archive


def test_a_task_that_keeps_killing_workers_ends_the_run_with_one_line(shared_data, tmp_path):
    """Every worker that starts coding a class dies. Past Dask's allowed failures the run ends: exit
    code 1, one line on stderr, and no archive, not even a partial one."""
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as local, \
            Client(local) as client:
        client.register_plugin(_KillOnce(os.fspath(tmp_path / "unused"), skip=0, every=True))
        out = tmp_path / "dask.mcz"
        result = CliRunner().invoke(main, ["compress", os.fspath(shared_data / "cmu" / "07"), "-o", os.fspath(out),
                                           "--dask", local.scheduler_address, "-q"])
    assert result.exit_code == 1, result.output
    errors = [line for line in result.stderr.splitlines() if line.startswith("mcz: error:")]
    assert len(errors) == 1 and errors[0].startswith("mcz: error: the Dask cluster could not run a task"), result.stderr
    assert "KilledWorker" in errors[0] and errors[0].endswith("no partial file was left behind")
    assert "Traceback" not in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_the_cluster_counts_every_task_done(shared_data, tmp_path, two_workers):
    """The progress bar's count: every task sent to the cluster is counted done by the end: a task
    per clip read, one for the class, a task per clip re-coded with the priors."""
    with cluster.on_cluster(two_workers.scheduler_address) as run:
        summary = writer.compress([os.fspath(shared_data / "cmu" / "07")], tmp_path / "a.mcz",
                                  mocapzip.archive.Settings(), jobs=run.workers)
        assert run.submitted == 2 * summary["clips"] + 1
        for _ in range(500):  # Dask counts a task done just after its result is there
            if run.done == run.submitted:
                break
            time.sleep(0.01)
        assert run.done == run.submitted


@pytest.mark.parametrize("address, message", [
    ("local:0", "expected local or local:N"),
    ("local:x", "expected local or local:N"),
    ("tcp://a b", "expected a scheduler address"),
])
def test_bad_addresses_are_refused(address, message):
    with pytest.raises(cluster.ClusterError, match=message):
        cluster.parse_address(address)


def test_local_takes_every_core_or_the_number_given():
    assert cluster.parse_address("local") == (os.cpu_count(), None)
    assert cluster.parse_address("local:1") == (1, None)
    assert cluster.parse_address("tcp://host:8786") == (None, "tcp://host:8786")


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:9", "foo://x:1", "tcp://localhost:notaport"])
def test_a_scheduler_not_there_is_one_line(shared_data, tmp_path, monkeypatch, address):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1)
    out = tmp_path / "x.mcz"
    result = CliRunner().invoke(main, ["compress", os.fspath(shared_data / "cmu" / "07"), "-o", os.fspath(out),
                                       "--dask", address, "-q"])
    assert result.exit_code == 1, result.output
    assert result.stderr.startswith(f"mcz: error: the Dask scheduler at {address} cannot be reached"), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_jobs_with_dask_is_a_usage_error(shared_data, tmp_path):
    result = CliRunner().invoke(main, ["compress", os.fspath(shared_data / "cmu" / "07"), "-o",
                                       os.fspath(tmp_path / "x.mcz"), "--dask", "local:2", "-j", "2"])
    assert result.exit_code == 2 and "-j has no meaning with --dask" in result.stderr


def test_a_reader_pickles_without_its_clips_and_its_copy_keeps_what_it_reads(shared_data):
    """What a Dask worker gets of the encoder's `ClipReader`: its settings, not the
    clips it keeps (those would travel with every map); the copy keeps the clips it reads."""
    source = find_clips([shared_data / "cmu" / "07"])[0]
    reader = ClipReader("aligned", budget_bytes=None)
    reader.keep(reader.read(source))
    assert reader.load(source) is reader.load(source)
    blob = pickle.dumps(reader)
    copy = pickle.loads(blob)
    assert copy._kept == {} and copy.budget_bytes is None and copy.representation_name == "aligned"
    assert len(blob) < 100_000
    first = copy.load(source)
    assert copy.load(source) is first
    assert reader._keeps_loads is False


def test_a_clip_that_cannot_be_read_fails_as_with_local_workers(shared_data, tmp_path):
    """An item's own error (here a bad number in an AMC, read by a worker) ends the run with the
    message local workers give: the file, the line, what was wrong. With --skip-bad, the clip is
    left out and the archive is -j 2's."""
    source = shared_data / "cmu" / "07"
    clips = tmp_path / "clips"
    clips.mkdir()
    (clips / "07.asf").write_bytes((source / "07.asf").read_bytes())
    lines = (source / "07_01.amc").read_text().splitlines(keepends=True)
    bad = next(i for i, line in enumerate(lines) if line.startswith("lowerback"))
    lines[bad] = "lowerback 1.0 nonsense 3.0\n"
    (clips / "07_01.amc").write_text("".join(lines))
    messages = []
    for how in (["-j", "2"], ["--dask", "local:2"]):
        result = CliRunner().invoke(main, ["compress", os.fspath(clips), "-o", os.fspath(tmp_path / "x.mcz"), "-q",
                                           *how])
        assert result.exit_code == 1
        messages.append(result.stderr)
    assert messages[0] == messages[1]
    assert messages[0].startswith(f"mcz: error: {clips / '07_01.amc'}:{bad + 1}:"), messages[0]
    assert not (tmp_path / "x.mcz").exists()
    (clips / "07_02.amc").write_bytes((source / "07_02.amc").read_bytes())  # with --skip-bad: one clip left
    archives = []
    for how in (["-j", "2"], ["--dask", "local:2"]):
        out = tmp_path / f"{how[1]}.mcz"
        result = CliRunner().invoke(main, ["compress", os.fspath(clips), "-o", os.fspath(out), "-q", "--skip-bad", *how])
        assert result.exit_code == 0, result.stderr
        archives.append(out.read_bytes())
    assert archives[0] == archives[1]
    with mocapzip.open(tmp_path / "local:2.mcz") as archive:
        assert archive.paths == ["07_02.amc"]


def test_a_worker_without_the_clients_folder_says_so():
    with pytest.raises(cluster.ClusterError, match="is not on the Dask worker .* at the same paths"):
        cluster._install("/no/such/folder/here", {})


# Imported by every worker of the run's LocalCluster (Dask's worker preload): the first class a
# worker starts coding is held, after the marker file is made, until the test's release file exists.
HOLD_A_CLASS = r"""
import os, time
from pathlib import Path
from mocapzip.archive.passes import class_coding

real = class_coding._class_task

def held(k):
    marker = Path(os.environ["MCZ_TEST_MARKER"])
    marker.touch()
    for _ in range(6000):
        if marker.with_suffix(".release").exists():
            break
        time.sleep(0.01)
    return real(k)

class_coding._class_task = held
"""


def test_ctrl_c_in_a_terminal_ends_a_dask_run_in_one_line(shared_data, tmp_path):
    """Ctrl-C in a terminal reaches the whole process group, the local cluster's workers included:
    mcz alone answers, in one line (no worker's traceback), leaves no file and no process behind.
    The signal comes while a worker holds a class (a state, not a clock)."""
    out, marker, hold = tmp_path / "out", tmp_path / "marker", tmp_path / "hold.py"
    out.mkdir()
    hold.write_text(HOLD_A_CLASS)
    env = {**os.environ, "MCZ_TEST_MARKER": os.fspath(marker), "DASK_DISTRIBUTED__WORKER__PRELOAD": f"['{hold}']"}
    proc = subprocess.Popen([MCZ, "compress", shared_data / "cmu" / "07", "-o", out / "db.mcz", "--dask", "local:2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True,  # a process group of its own, as in a terminal
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    while not marker.exists():
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGINT)
    marker.with_suffix(".release").touch()
    _, stderr = proc.communicate(timeout=DEADLINE)
    assert proc.returncode == 1, stderr
    assert [line for line in stderr.splitlines() if not line.startswith("mcz: warning:")] == [
        "mcz: error: interrupted (SIGINT); no partial file was left behind"], stderr
    assert list(out.iterdir()) == []
    with pytest.raises(ProcessLookupError):  # every worker has gone with it
        for _ in range(500):
            os.killpg(proc.pid, 0)
            time.sleep(0.02)


@pytest.mark.slow  # about 10 s: the fast tier keeps the other cluster tests
def test_a_worker_with_two_threads_writes_the_same_archive(shared_data, tmp_path):
    """`dask worker` runs a task per core on threads by default: both classes (02, and 07 and 09
    pooled) would start at once in one process, where a task's state and the encoder's live in
    module dicts. One task at a time runs there, and the archive is -j 2's."""
    subjects = [shared_data / "cmu" / name for name in ("02", "07", "09")]
    mocapzip.compress(subjects, tmp_path / "j2.mcz", jobs=2)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=":0") as local:
        summary = mocapzip.compress(subjects, tmp_path / "dask.mcz", dask=local.scheduler_address)
    assert summary["clips"] == 30
    assert len(mocapzip.archive.info(tmp_path / "dask.mcz")["classes"]) == 2
    assert (tmp_path / "dask.mcz").read_bytes() == (tmp_path / "j2.mcz").read_bytes()


def test_a_local_cluster_leaves_the_blas_variables_as_they_were(monkeypatch):
    """Starting a LocalCluster sets the BLAS thread variables for its workers in this process too; a
    later compress here would take them for the user's choice (`parallel.one_blas_thread`) and run
    numpy's BLAS, already loaded, on every core: another archive than the command line's."""
    for name in BLAS_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    with cluster.on_cluster("local:1"):
        assert not [name for name in BLAS_THREAD_VARIABLES if name in os.environ]
    assert not [name for name in BLAS_THREAD_VARIABLES if name in os.environ]


@pytest.mark.slow  # about 10 s: the fast tier keeps the other cluster tests
def test_two_runs_on_one_scheduler_at_once(shared_data, tmp_path, two_workers):
    """Two `mcz compress` on one scheduler at the same time: each worker runs one task at a time and
    installs each task's own state, and a run that ends clears only its own: both archives are -j 2's."""
    subjects = ("02", "09")
    runs = {name: subprocess.Popen([MCZ, "compress", shared_data / "cmu" / name, "-o", tmp_path / f"{name}.mcz",
                                    "--dask", two_workers.scheduler_address, "-q"], stderr=subprocess.PIPE, text=True)
            for name in subjects}
    for name, proc in runs.items():
        _, stderr = proc.communicate(timeout=DEADLINE)
        assert proc.returncode == 0, stderr
    for name in subjects:
        mocapzip.compress([shared_data / "cmu" / name], tmp_path / f"{name}-j2.mcz", jobs=2)
        assert (tmp_path / f"{name}.mcz").read_bytes() == (tmp_path / f"{name}-j2.mcz").read_bytes()


def _doubled(item: int) -> int:
    return 2 * item


def test_a_map_whose_state_is_lost_with_its_worker_still_ends(two_workers):
    """Dask's memory manager keeps one copy of a value once no task waits for it. If the worker that
    holds the map's only copy of its state dies, Dask makes the state again (it is a task, not
    scattered data, which Dask would forget, cancelling every task that needs it), and every result
    comes back."""
    with Client(two_workers) as client:
        run = cluster.Cluster(client, local=True)
        results = run.imap(_doubled, range(40))
        assert next(results) == 0
        holders = []
        for _ in range(500):  # until the memory manager has dropped the spare copy
            client.amm.run_once()
            holders = [workers for key, workers in client.who_has().items() if key.startswith("state-")]
            if len(holders) == 1 and len(holders[0]) == 1:
                break
            time.sleep(0.01)
        assert len(holders) == 1 and len(holders[0]) == 1, holders
        (pid,) = client.run(os.getpid, workers=list(holders[0])).values()
        os.kill(pid, signal.SIGKILL)
        assert list(results) == [2 * i for i in range(1, 40)]

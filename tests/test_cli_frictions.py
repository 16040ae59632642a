"""CLI frictions a new user hit (issue 14): `-o -`, options --lossless ignores, files that are not
archives, the progress bar's unit, `info`'s wording and clip table, plurals, Ctrl-C at start-up."""

from __future__ import annotations

import gc
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest
from click.testing import CliRunner

from mocapzip import archive
from mocapzip.archive.passes import class_coding
from mocapzip import progress
from mocapzip.cli.main import main
from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveError, ArchiveReader

GOLDEN_LOSSY = Path(__file__).parent / "golden" / f"lossy_v{FORMAT_VERSION}.mcz"
NOT_HDF5 = "header: not an mcz archive (not an HDF5 file)"


def run(*args):
    return CliRunner().invoke(main, [os.fspath(a) for a in args])


@pytest.mark.parametrize("command, what", [("compress", "file"), ("decompress", "folder")])
def test_output_to_stdout_is_a_usage_error(tmp_path, monkeypatch, command, what):
    monkeypatch.chdir(tmp_path)
    source = GOLDEN_LOSSY if command == "decompress" else tmp_path / "x.amc"
    result = run(command, source, "-o", "-")
    assert result.exit_code == 2
    assert "writing to stdout is not supported" in result.stderr and f"name a {what}" in result.stderr
    assert list(tmp_path.iterdir()) == []  # no file or folder named "-"


@pytest.mark.parametrize("command, what", [("compress", "file"), ("decompress", "folder"), ("convert", "folder")])
def test_an_empty_output_is_a_usage_error(tmp_path, monkeypatch, shared_data, command, what):
    """`-o ''` named nothing: decompress and convert wrote into the current folder, compress failed
    with `[Errno 2] No such file or directory: ''`."""
    monkeypatch.chdir(tmp_path)
    source = GOLDEN_LOSSY if command == "decompress" else shared_data / "cmu-bvh/10/10_03.bvh"
    result = run(command, source, "-o", "")
    assert result.exit_code == 2
    assert result.stderr == (f"mcz {command}: Invalid value for '-o' / '--output': an empty name names no {what}; "
                             f"name one (see mcz {command} --help)\n")
    assert list(tmp_path.iterdir()) == []


GOLDEN_ARGUMENT = os.fspath(GOLDEN_LOSSY)
USAGE_ERRORS = [  # (arguments, what the one line says): click's own checks, and the commands' own refusals
    (["compress", "x.amc"], "mcz compress: Missing option '-o' / '--output'"),
    (["compress", "x.amc", "-o", "x.mcz", "-e", "-1"], "mcz compress: Invalid value for '-e' / '--error': -1.0 is not in the range x>0"),
    (["compress", "x.amc", "-o", "x.mcz", "-e", "abc"], "mcz compress: Invalid value for '-e' / '--error': 'abc' is not a valid float range"),
    (["compress", "x.amc", "-o", "x.mcz", "-e"], "mcz compress: Option '-e' requires an argument"),  # click gives it no context
    (["compress", "x.amc", "-o", "x.mcz", "--knot-spacing", "5"], "mcz compress: --knot-spacing is for --transform poly, not dct-edges"),
    (["compress", "x.amc", "-o", "x.mcz", "--split", "1,2"],
     "mcz compress: Invalid value for --split: expected three non-negative shares R,P,T, e.g. 0.2,0.4,0.4"),
    (["compress"], "mcz compress: Missing argument 'INPUTS...'"),
    (["decompress"], "mcz decompress: Missing argument 'ARCHIVE'"),
    (["decompress", GOLDEN_ARGUMENT, "-o", "out", "--bogus"], "mcz decompress: No such option '--bogus'. Did you mean '--jobs'?"),
    (["info", "-j", "2", GOLDEN_ARGUMENT], "mcz info: No such option '-j'"),
    (["test", "-j", "0", GOLDEN_ARGUMENT], "mcz test: Invalid value for '-j' / '--jobs': 0 is not in the range x>=1"),
    (["inspect", "x.bvh", "--units", "furlongs"],
     "mcz inspect: Invalid value for '--units': 'furlongs' is not one of 'cm', 'mm', 'm', 'in'"),
    (["convert", "x.bvh"], "mcz convert: Missing option '-o' / '--output'"),
    (["bench", "x.amc", "--codec", "gzip"], "mcz bench: Invalid value for --codec: 'gzip': choose from mcz, hou, hou-shared, xz, zstd"),
    (["classify", "--train", "labels.csv", "a.amc"], "mcz classify: Missing option '--test'"),
    (["classify", "--train", "labels.csv", "a.amc", "--test", "b.amc", "--threshold", "abc"],
     "mcz classify: Invalid value for --threshold: expected 'auto' or a number (a log density)"),
    (["plot", GOLDEN_ARGUMENT, "--against", ".", "-o", "x.jpg"],
     "mcz plot: Invalid value for '-o' / '--output': 'x.jpg': plot writes .png or .svg files (the suffix says which)"),
    (["plot", GOLDEN_ARGUMENT, "-o", "x.png"], "mcz plot: Missing option '--against'"),
    (["view", GOLDEN_ARGUMENT], "mcz view: Missing argument 'CLIP'"),
    (["view", GOLDEN_ARGUMENT, "x.amc", "-o", "x.gif", "--frames", "3"],
     "mcz view: Invalid value for '--frames': '3': expected A:B, frame numbers from 0 (e.g. 0:240, 120:)"),
    (["remove", GOLDEN_ARGUMENT], "mcz remove: Missing argument 'PATTERN...'"),
    (["remove", GOLDEN_ARGUMENT, "09_01.amc"],
     "mcz remove: name the new archive with -o, or give -f to replace ARCHIVE in place"),
    (["append", GOLDEN_ARGUMENT, "x/", "-o", "x.mcz", "--under", "../x"],
     "mcz append: Invalid value for '--under': must be a relative folder without '.' or '..', got '../x'"),
    (["append", GOLDEN_ARGUMENT], "mcz append: Missing argument 'INPUTS...'"),
    (["bogus"], "mcz: No such command 'bogus'"),
    (["--bogus"], "mcz: No such option '--bogus'"),
]


@pytest.mark.parametrize("arguments, said", USAGE_ERRORS, ids=[" ".join(a) for a, _ in USAGE_ERRORS])
def test_a_usage_error_is_one_line_naming_the_command_and_its_help(tmp_path, monkeypatch, arguments, said):
    """click printed a usage error in three or four lines (usage, a hint, a blank line, the error)."""
    monkeypatch.chdir(tmp_path)
    result = run(*arguments)
    assert result.exit_code == 2
    command = said.split(":")[0]
    assert result.stderr == f"{said} (see {command} --help)\n"
    assert list(tmp_path.iterdir()) == []


def test_every_command_has_its_usage_error_tested():
    assert {arguments[0] for arguments, _ in USAGE_ERRORS} >= set(main.commands)


def test_mcz_alone_still_prints_the_help():
    result = run()
    assert result.exit_code == 2 and "Run `mcz COMMAND --help`" in result.stderr


@pytest.mark.parametrize("command, in_the_way", [("decompress", "dangling link"), ("convert", "dangling link"),
                                                 ("convert", "file below")])
def test_an_output_folder_that_is_no_folder_is_refused_even_with_force(tmp_path, shared_data, command, in_the_way):
    """`-o` a symbolic link to nothing, with -f, was refused as `already exists (use -f/--force to
    overwrite)`; a file where a folder of the output goes is not what -f replaces either (`-o` a
    file is a usage error already). Refused in one line before any file is written."""
    source = tmp_path / "in"
    if command == "decompress":
        source = GOLDEN_LOSSY
    else:
        (source / "sub").mkdir(parents=True)
        for name in ("09.asf", "09_01.amc"):
            (source / "sub" / name).symlink_to(shared_data / "cmu/09" / name)
    out = tmp_path / "out"
    if in_the_way == "dangling link":
        out.symlink_to(tmp_path / "nowhere")
        blocked, kind = out, "a symbolic link to nothing"
    else:  # where the folder of the file written goes: out/sub/09_01.bvh
        out.mkdir()
        (out / "sub").write_bytes(b"x")
        blocked, kind = out / "sub", "a file"
    before = sorted(tmp_path.rglob("*"))
    result = run(command, source, "-o", out, "-f")
    assert result.exit_code == 1
    assert result.stderr == f"mcz: error: {blocked}: not a folder but {kind}: files cannot be written under it\n"
    assert sorted(tmp_path.rglob("*")) == before


@pytest.mark.parametrize("option", [["-e", "1.0"], ["--error", "0.5"], ["-r", "channels"], ["-t", "dwt"],
                                    ["--wavelet", "db2"], ["--level", "2"], ["--split", "1,1,1"], ["--segment"]])
def test_lossy_only_options_refused_with_lossless(tmp_path, option):
    """Given explicitly, even at its default value (-e 1.0): --lossless would silently ignore it."""
    result = run("compress", tmp_path / "x.amc", "-o", tmp_path / "db.mcz", "--lossless", *option)
    assert result.exit_code == 2
    name = {"-e": "--error", "-r": "--representation", "-t": "--transform"}.get(option[0], option[0])
    assert result.stderr.startswith(f"mcz compress: {name} has no meaning with --lossless")
    assert not (tmp_path / "db.mcz").exists()


def test_several_lossy_only_options_named_together(tmp_path):
    result = run("compress", tmp_path / "x.amc", "-o", tmp_path / "db.mcz", "-e", "2", "--lossless", "--segment")
    assert result.exit_code == 2 and "--error, --segment have no meaning with --lossless" in result.stderr


@pytest.fixture
def not_archives(tmp_path, shared_data):
    (tmp_path / "empty.mcz").write_bytes(b"")
    (tmp_path / "notes.txt").write_text("hello\n")
    (tmp_path / "09_01.amc").write_bytes((shared_data / "cmu" / "09" / "09_01.amc").read_bytes())
    return [tmp_path / "empty.mcz", tmp_path / "notes.txt", tmp_path / "09_01.amc"]


@pytest.mark.parametrize("command", ["info", "test"])
def test_not_an_archive_in_one_line(not_archives, command):
    for path in not_archives:
        result = run(command, path)
        assert result.exit_code == 1 and result.stdout == ""
        assert result.stderr == f"mcz: error: {path}: {NOT_HDF5}\n"


def test_hdf5_signature_after_a_user_block_is_still_hdf5(tmp_path):
    """HDF5 also looks at offsets 512, 1024, ...: such a file is HDF5, only not ours."""
    path = tmp_path / "userblock.h5"
    with h5py.File(path, "w", userblock_size=512) as f:
        f.attrs["magic"], f.attrs["format_version"] = "something else", 1
    with pytest.raises(ArchiveError, match="header: not a mocapzip archive .magic"):
        ArchiveReader(path)


def test_progress_counts_frames(tmp_path, shared_data, monkeypatch):
    """The coding bar's total is the frames coded, advanced class by class (one subject: not 0/1)."""
    bars = []
    real = class_coding.progress

    def recording(iterable=None, **kwargs):
        bar = real(iterable, **kwargs)
        if iterable is None:
            bars.append((kwargs, bar))
            updates = bar.updates = []
            bar.update = lambda n=1: updates.append(n)
        return bar

    monkeypatch.setattr(class_coding, "progress", recording)
    clips = [shared_data / "cmu" / "09" / "09_01.amc", shared_data / "cmu" / "09" / "09_03.amc"]
    summary = archive.compress(clips, tmp_path / "db.mcz", archive.Settings(error_cm=2.0), jobs=1)
    [(kwargs, bar)] = bars
    assert kwargs["unit"] == "frame" and kwargs["total"] == summary["frames"] == sum(bar.updates)


def test_quiet_progress_is_disabled():
    with progress.quieted(), progress.progress(total=10, unit="frame") as bar:
        bar.update(10)
        assert bar.disable


def test_info_text_table_wording_and_plurals():
    golden = GOLDEN_LOSSY.with_name("lossy_v6.mcz")  # written with --classes subject: a class of one clip
    result = run("info", golden)
    assert result.exit_code == 0
    report = json.loads(run("info", "--json", golden).stdout)
    text = result.stdout
    assert f"largest clip mean error {report['worst_error_cm']:.3f} cm (max {report['largest_max_error_cm']:.3f} cm)" in text
    assert report["largest_mean_error_cm"] == report["worst_error_cm"] == max(c["error_cm"] for c in report["clips"])
    assert report["largest_max_error_cm"] == max(c["max_error_cm"] for c in report["clips"])
    assert "worst clip error" not in text and "1 clips" not in text and "class 09: 1 clip, " in text
    names = [c["name"] for c in report["classes"]]
    for clip in report["clips"]:
        row = (f"{clip['frames']:>7}  {names[clip['class']]:<8}  {clip['error_cm']:>8.3f}  {clip['p99_error_cm']:>8.3f}  "
               f"{clip['max_error_cm']:>8.3f}  {'-':>9}  {clip['patched_frames']:>7}")  # vertex: format 13 on
        assert any(line.startswith(clip["path"]) and line.endswith(row) for line in text.splitlines())
    short = run("info", "--no-clips", golden).stdout
    assert "mean cm" not in short and short.splitlines() == [line for line in text.splitlines()
                                                              if not line.startswith(("clip ", "09_01", "64_01"))]


def test_test_and_decompress_summaries_say_one_clip(tmp_path):
    result = run("decompress", GOLDEN_LOSSY, "-o", tmp_path / "out", "--clip", "09_*")
    assert result.exit_code == 0 and result.stderr.startswith("1 clip, 148 frames -> ")
    assert run("test", GOLDEN_LOSSY).stderr == f"{GOLDEN_LOSSY}: OK (3 clips)\n"


# The child delays the import of click (which cli/main.py makes first, as a real slow start-up
# would) until the test has interrupted it: no timing guess decides where the signal lands.
SLOW_START = r"""
import os, sys, time
from pathlib import Path

class SlowClick:
    def find_spec(self, name, path=None, target=None):
        if name == "click":
            Path(os.environ["MCZ_TEST_MARKER"]).touch()
            time.sleep(60)
        return None

sys.meta_path.insert(0, SlowClick())
from mocapzip.cli.main import main
main(prog_name="mcz")
"""


def test_ctrl_c_during_start_up_is_one_line(tmp_path):
    marker = tmp_path / "importing"
    env = {**os.environ, "MCZ_TEST_MARKER": os.fspath(marker)}
    # SIGINT as a terminal gives it: a test run started in the background (nohup, `&`) ignores it, and children inherit that
    child = subprocess.Popen([sys.executable, "-c", SLOW_START, "info", os.fspath(GOLDEN_LOSSY)], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        for _ in range(600):
            if marker.exists() or child.poll() is not None:
                break
            time.sleep(0.05)
        assert marker.exists(), child.communicate()
        child.send_signal(signal.SIGINT)
        stdout, stderr = child.communicate(timeout=30)
    finally:
        child.kill()
    assert stderr == "mcz: error: interrupted (SIGINT)\n" and stdout == ""
    assert child.returncode in (1, 130, -signal.SIGINT)


def test_cli_choices_are_the_registered_stages():
    """`-t` and `-r` offer exactly what the registries build (`-t none` once died with 'unknown stage id')."""
    from mocapzip.cli import choices
    from mocapzip.stages import get_stage, stage_ids

    assert sorted(choices.TRANSFORMS) == sorted(stage_ids("transform"))
    assert sorted(choices.REPRESENTATIONS) == sorted(stage_ids("representation"))
    for name in choices.TRANSFORMS:
        assert get_stage("transform", {"id": name}).get_config()["id"] == name


@pytest.mark.parametrize("change, message", [
    ({"coefficient_coder": "zstd"}, "coefficient_coder 'zstd' is not written by format"),
    ({"transform": {"id": "none"}}, "unknown transform id 'none'"),
    ({"representation": "quaternions"}, "unknown representation id 'quaternions'"),
])
def test_settings_an_archive_cannot_hold_are_refused_before_any_input_is_read(tmp_path, change, message):
    from dataclasses import replace

    from mocapzip.archive import Settings, compress

    with pytest.raises((ValueError, KeyError), match=message):
        compress([tmp_path / "no such folder"], tmp_path / "x.mcz", replace(Settings(), **change))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["info", "info --json", "inspect"])
def test_a_reader_gone_from_stdout_ends_the_command_quietly(shared_data, command):
    """`mcz info db.mcz | head`: the reader of stdout has gone before mcz writes. mcz stops as cat
    would, with exit code 1 and nothing on stderr (not an error line, not Python's broken-pipe noise)."""
    source = shared_data / "cmu" / "07" if command == "inspect" else GOLDEN_LOSSY
    proc = subprocess.Popen([Path(sys.executable).with_name("mcz"), *command.split(), source], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # no reader left: the first write fails with EPIPE, whenever it comes
    _, stderr = proc.communicate(timeout=120)
    assert (proc.returncode, stderr) == (1, b"")


# A command that writes to a pipe of its own whose reader has gone, run with stdout a live pipe.
OTHER_PIPE_BROKEN = r"""
import os
import click
from mocapzip.cli.errors import reports_errors

@click.command()
@reports_errors
def command():
    read_end, write_end = os.pipe()
    os.close(read_end)
    os.write(write_end, b"x")

command()
"""


def test_a_broken_pipe_that_is_not_stdout_is_an_error_line():
    """Only stdout's reader going away ends a command quietly; a pipe of the command's own that
    breaks (a child's stdin, a FIFO given as a file) is a one-line error like any other."""
    result = subprocess.run([sys.executable, "-c", OTHER_PIPE_BROKEN], capture_output=True, text=True, timeout=120)
    assert (result.returncode, result.stdout) == (1, "")
    assert result.stderr == "mcz: error: [Errno 32] Broken pipe\n"


def test_a_closed_stdout_is_not_an_error(tmp_path):
    """Run with stdout closed (`mcz decompress ... >&-`, as some schedulers start jobs): the files are
    written and the command succeeds, with nothing on stderr."""
    out = tmp_path / "out"
    result = subprocess.run([Path(sys.executable).with_name("mcz"), "decompress", GOLDEN_LOSSY, "-o", out, "-q"],
                            capture_output=False, stderr=subprocess.PIPE, text=True, timeout=120,
                            preexec_fn=lambda: os.close(1))
    assert (result.returncode, result.stderr) == (0, "")
    assert len(list(out.iterdir())) >= 2


def test_importing_turns_the_collector_off_and_freezes_what_was_made(monkeypatch):
    from mocapzip.cli import importing

    monkeypatch.setattr(gc, "freeze", lambda: frozen.append(gc.isenabled()))
    frozen = []
    assert gc.isenabled()
    with importing():
        assert not gc.isenabled()
    assert gc.isenabled() and frozen == [False]  # frozen before collection is back on
    with pytest.raises(ImportError), importing():
        raise ImportError("a missing module")
    assert gc.isenabled() and frozen == [False, False]
    gc.disable()
    try:
        with importing():
            pass
        assert not gc.isenabled()  # a collector that was off stays off
    finally:
        gc.enable()


def test_commands_collect_garbage_for_their_work_and_leave_it_as_it_was(tmp_path, monkeypatch):
    """A command works with its imports frozen (`importing`) and the collector on; after it, failed
    or not, nothing stays frozen, unless something was frozen before it."""
    seen = {}
    real_info = archive.info

    def info(path):
        seen["working"], seen["frozen"] = gc.isenabled(), gc.get_freeze_count()
        return real_info(path)

    monkeypatch.setattr(archive, "info", info)
    assert gc.get_freeze_count() == 0
    assert run("info", GOLDEN_LOSSY).exit_code == 0
    assert seen["working"] and seen["frozen"] > 0
    assert gc.isenabled() and gc.get_freeze_count() == 0
    assert run("info", tmp_path / "missing.mcz").exit_code == 1
    assert gc.isenabled() and gc.get_freeze_count() == 0
    gc.freeze()  # a caller's own frozen objects
    try:
        callers = gc.get_freeze_count()
        assert run("info", GOLDEN_LOSSY).exit_code == 0
        assert gc.get_freeze_count() >= callers > 0
    finally:
        gc.unfreeze()


def test_an_archive_that_appears_while_compress_writes_is_refused_in_the_clis_words(shared_data, tmp_path, monkeypatch):
    """The container refuses a target that appeared after compress checked it (issue 40); the CLI
    says so in its own words (-f), not in the Python API's (`overwrite=True`)."""
    from mocapzip.formats import mcz

    target, write = tmp_path / "x.mcz", mcz._write_hdf5

    def appearing(*args, **kwargs):
        target.write_bytes(b"")  # another process's file, made while the archive is written
        return write(*args, **kwargs)

    monkeypatch.setattr(mcz, "_write_hdf5", appearing)
    result = run("compress", shared_data / "cmu/09/09_01.amc", "--asf", shared_data / "cmu/09/09.asf", "--lossless",
                 "-o", target)
    assert result.exit_code == 1
    assert result.stderr == f"mcz: error: {target}: already exists (use -f/--force to overwrite)\n"
    assert target.read_bytes() == b""


def test_running_out_of_memory_is_one_line(monkeypatch):
    """A MemoryError (numpy's or numba's, under a limit on address space) was a traceback: a clip
    at the limits decoded on two threads took about 1 GB of address space."""
    from mocapzip.archive import reader

    def exhausted(self, jobs=1):
        raise MemoryError("Allocation failed (probably too large).")

    monkeypatch.setattr(reader.Archive, "verify", exhausted)
    result = CliRunner().invoke(main, ["test", str(GOLDEN_LOSSY)])
    assert result.exit_code == 1 and isinstance(result.exception, SystemExit)
    assert result.stderr == "mcz: error: out of memory; no partial file was left behind\n"


@pytest.mark.parametrize("option", [["-e", "1e-17"], ["--max-error", "1e-300"], ["--contact-error", "1e-300"]])
def test_an_error_finer_than_any_capture_is_a_usage_error(shared_data, tmp_path, option):
    """Before: `-e 1e-17` on cmu/09 ended in a traceback (`ValueError: coefficients must be below
    2**62 in magnitude`: steps that fine); `--max-error 1e-300` printed numpy's divide-by-zero
    warnings before its refusal. Exact values are --lossless's."""
    result = CliRunner().invoke(main, ["compress", str(shared_data / "cmu" / "09"), "-o", str(tmp_path / "x.mcz"),
                                       "-q", *option])
    assert result.exit_code == 2, result.output
    name = {"-e": "error_cm", "--max-error": "max_error_cm", "--contact-error": "contact_error_cm"}[option[0]]
    assert result.stderr == (f"mcz compress: {name} must be from 1e-06 to 1e+06 cm (exact values: --lossless), "
                             f"got {option[1]} (see mcz compress --help)\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["decompress", "convert"])
def test_a_folder_where_a_file_goes_is_refused_before_any_file_is_written(tmp_path, shared_data, command):
    """With -f, a folder at the path of a file to write was found only when that file was renamed
    over it: the files before it stayed written, and the one line named the temporary file
    (`out/.mcz-<hex>.tmp: Is a directory`). -f replaces files, not folders."""
    out = tmp_path / "out"
    if command == "decompress":
        source, blocked = GOLDEN_LOSSY, out / "64_01.amc"  # after 09_01.amc, in the archive's order
    else:
        source, blocked = tmp_path / "in", out / "sub" / "09_02.bvh"
        (source / "sub").mkdir(parents=True)
        for name in ("09.asf", "09_01.amc", "09_02.amc"):
            (source / "sub" / name).symlink_to(shared_data / "cmu/09" / name)
    blocked.mkdir(parents=True)
    before = sorted(tmp_path.rglob("*"))
    result = run(command, source, "-o", out, "-f")
    assert result.exit_code == 1
    assert result.stderr == (f"mcz: error: {blocked}: is a folder: a file cannot be written in its place (-f replaces "
                             "files, not folders)\n")
    assert sorted(tmp_path.rglob("*")) == before


def test_a_file_that_cannot_replace_what_is_there_is_named_not_its_temporary_file(tmp_path):
    """What the rename over it says (a folder made there meanwhile) names the file, as a full disk does."""
    from mocapzip.formats.text import write_file_atomically

    (tmp_path / "x.amc").mkdir()
    with pytest.raises(OSError) as raised:
        write_file_atomically(tmp_path / "x.amc", b"data")
    assert raised.value.filename == str(tmp_path / "x.amc")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.amc"]  # and the temporary file is gone

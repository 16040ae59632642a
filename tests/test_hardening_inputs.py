"""Hostile inputs through the `mcz` command line (issue 5, item 1) and `compress --skip-bad`.

The corpus (tests/hostile_inputs.py) is real CMU data damaged one way per folder. Every
refusal must be ONE line naming the file (and line) and the problem, exit 1, no traceback,
and no output or temporary file left behind.
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

import hostile_inputs
from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats import amc as amc_module
from mocapzip.formats import mcz as mcz_module
from tests.test_hardening_bvh import root_at_the_limit

GOLDEN_LOSSLESS = Path(__file__).parent / "golden" / "lossless_v1.mcz"


def run(*args):
    return CliRunner().invoke(main, [os.fspath(a) for a in args])


@pytest.fixture(scope="module")
def corpus(tmp_path_factory, shared_data):
    root = tmp_path_factory.mktemp("hostile")
    return root, {case.name: case for case in hostile_inputs.build(root, shared_data)}


@pytest.fixture
def deny_unreadable(corpus, monkeypatch):
    """Make chmod 000 deny reading even as root, exactly where files and folders are opened.

    Root reads any file, so there the kernel cannot refuse; this applies the permission
    bits the way the kernel does for everyone else, in os.open (every input reader opens
    through formats.text.open_regular_file) and os.scandir (os.walk lists folders with it).
    As a normal user nothing is patched: the kernel refuses.
    """
    root, _ = corpus
    if not hostile_inputs.is_readable_anyway(root / "unreadable_file" / hostile_inputs.AMC_NAME):
        return
    real_open, real_scandir = os.open, os.scandir

    def check(path) -> None:
        try:
            unreadable = not os.stat(path).st_mode & 0o444
        except (OSError, TypeError, ValueError):
            return  # the real call reports it
        if unreadable:
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fspath(path))

    def guarded_open(path, flags, *args, **kwargs):
        if flags & os.O_ACCMODE == os.O_RDONLY and kwargs.get("dir_fd") is None:
            check(path)
        return real_open(path, flags, *args, **kwargs)

    def guarded_scandir(path="."):
        check(path)
        return real_scandir(path)

    monkeypatch.setattr(os, "open", guarded_open)
    monkeypatch.setattr(os, "scandir", guarded_scandir)


def error_line(result) -> str:
    """The single stderr line of a refused command (no traceback, nothing on stdout)."""
    assert result.exit_code == 1, (result.exit_code, result.output)
    assert isinstance(result.exception, SystemExit), result.exception
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("mcz: error: "), result.stderr
    assert result.stdout == ""
    return lines[0]


def names(case) -> str:
    """The regex a message must match: file, line where there is one, then the problem."""
    where = re.escape(case.file) + (f":{case.line}" if case.line is not None else "")
    return where + r": .*" + re.escape(case.problem)


def refusal_problems(case, folder: Path, out: Path) -> list[str]:
    """What is wrong with how `compress` and `inspect` refuse this case (empty: all good)."""
    inputs = [os.path.normpath(folder / i) for i in case.inputs]
    try:
        line = error_line(run("compress", *inputs, "-o", out / "db.mcz", "--lossless", "-q"))
    except AssertionError as exc:
        return [f"compress: {exc}"]
    problems = [] if re.search(names(case), line) else [f"compress says {line!r}, expected {names(case)!r}"]
    if os.listdir(out):
        problems.append(f"compress left {os.listdir(out)}")
    inspected = run("inspect", *inputs)
    if case.inspect_warns:  # inspect lists clips without a skeleton or a truncated last frame; it names the problem
        warned = [w for w in inspected.stderr.splitlines() if w.startswith("mcz: warning: ") and re.search(names(case), w)]
        if inspected.exit_code != 0 or not warned:
            problems.append(f"inspect: exit {inspected.exit_code}, {inspected.output!r}")
    else:
        try:
            if error_line(inspected) != line:
                problems.append(f"inspect says {inspected.stderr!r}, compress {line!r}")
        except AssertionError as exc:
            problems.append(f"inspect: {exc}")
    return problems


def test_bad_inputs_are_refused_in_one_line_and_leave_nothing(corpus, deny_unreadable, tmp_path):
    root, cases = corpus
    refused = list(cases.values())
    failures = {}
    for case in refused:
        out = tmp_path / case.name
        out.mkdir()
        problems = refusal_problems(case, root / case.name, out)
        if problems:
            failures[case.name] = problems
    print(f"{len(refused) - len(failures)} of {len(refused)} bad inputs refused cleanly")
    assert failures == {}


@pytest.mark.parametrize("name", ["truncated_mid_frame", "truncated_mid_number"])
def test_truncated_last_frame_is_dropped_with_a_warning_unless_lossless(corpus, tmp_path, name):
    """A copy cut inside its last frame keeps every complete frame, the cut frame named in a
    warning; --lossless, which could not give the file back, refuses it."""
    root, cases = corpus
    case = cases[name]
    refused = error_line(run("compress", root / name, "-o", tmp_path / "db.mcz", "--lossless"))
    assert re.search(names(case), refused) and refused.endswith(": --lossless cannot keep a partial frame")
    result = run("compress", root / name, "-o", tmp_path / "db.mcz", "--json")
    assert result.exit_code == 0, result.output
    (warning,) = result.stderr.splitlines()
    assert warning.startswith("mcz: warning: ") and re.search(names(case), warning), warning
    assert warning.endswith("); dropped")
    assert json.loads(result.stdout)["frames"] == case.frames
    inspected = run("inspect", "--json", root / name)
    assert inspected.exit_code == 0 and inspected.stderr.splitlines() == [warning]
    assert json.loads(inspected.stdout)["total"]["frames"] == case.frames


def test_unreadable_file_and_folder_are_really_unreadable(corpus, deny_unreadable):
    """The permission cases test a denial, real or (as root) applied by `deny_unreadable`."""
    root, _ = corpus
    with pytest.raises(PermissionError):
        amc_module.read_amc(root / "unreadable_file" / hostile_inputs.AMC_NAME)
    with pytest.raises(PermissionError):
        os.scandir(root / "unreadable_folder" / "09")


@pytest.fixture(scope="module")
def mixed(tmp_path_factory, corpus, shared_data):
    """The whole corpus plus a folder of good clips: what --skip-bad must sort out."""
    root, cases = corpus
    good = tmp_path_factory.mktemp("good")
    subject = shared_data / hostile_inputs.SUBJECT
    for name in ("09.asf", "09_02.amc", "09_03.amc"):
        shutil.copy(subject / name, good / name)
    return root, cases, good


def test_skip_bad_compresses_the_rest_and_lists_what_was_skipped(mixed, deny_unreadable, tmp_path):
    root, cases, good = mixed
    archive = tmp_path / "db.mcz"
    result = run("compress", root, good, "-o", archive, "--lossless", "--skip-bad", "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)

    skipped = {entry["path"]: entry["error"] for entry in summary["skipped"]}
    bad = {}  # every clip of the corpus, or the folder that cannot be listed
    for name, case in cases.items():
        for path in (root / name).iterdir():
            if path.name.lower().endswith(".amc") or (path.is_dir() and not path.is_symlink()):
                bad[f"{name}/{path.name}"] = case
    assert set(skipped) == set(bad)
    for path, case in bad.items():
        # inside a folder, a looping link is found by the walk and fails when opened
        problem = "Too many levels of symbolic links" if "symlink" in path else case.problem
        assert problem in skipped[path] and case.file in skipped[path], (path, skipped[path])
    warnings = [line for line in result.stderr.splitlines() if line.startswith("mcz: warning: skipped ")]
    assert warnings == [f"mcz: warning: skipped {path}: {error}" for path, error in skipped.items()]

    kept = {"09_02.amc", "09_03.amc"}
    assert summary["clips"] == len(kept)
    with Archive(archive) as opened:
        assert opened.meta["skipped"] == summary["skipped"]
        assert {row["path"] for row in opened.clips} == kept
    assert json.loads(run("info", "--json", archive).stdout)["skipped"] == summary["skipped"]
    out = tmp_path / "out"
    assert run("decompress", archive, "-o", out, "--clip", "09_0?.amc", "-q").exit_code == 0
    for name in ("09_02.amc", "09_03.amc"):  # lossless: the good clips come back byte for byte
        assert (out / name).read_bytes() == (good / name).read_bytes()


def test_skip_bad_with_nothing_left_is_an_error(mixed, tmp_path):
    root, cases, _ = mixed
    folder, out = tmp_path / "bad", tmp_path / "out"
    folder.mkdir()
    out.mkdir()
    shutil.copy(root / "value_nan" / hostile_inputs.ASF_NAME, folder)
    bad = [name for name in cases if name.startswith("value_")]
    for name in bad:
        shutil.copy(root / name / hostile_inputs.AMC_NAME, folder / f"{name}.amc")
    result = run("compress", folder, "-o", out / "db.mcz", "--lossless", "--skip-bad")
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == len(bad) + 1 and all(line.startswith("mcz: warning: skipped ") for line in lines[:-1])
    assert re.fullmatch(rf"mcz: error: .*: nothing to compress: all {len(bad)} inputs were skipped", lines[-1])
    assert os.listdir(out) == []


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_skip_bad_leaves_out_a_clip_that_no_coding_holds(shared_data, tmp_path, jobs):
    """Issue 40: a clip refused while its class is coded (TargetError: a real clip whose root stands
    near x = 1e9, the most a file may hold, decodes a hair past it) stopped the run even with
    --skip-bad. Now it is left out and listed as a clip that cannot be read is, and nothing of it
    stays: every stream is the one of the inputs without it, meta too but for `skipped`."""
    cmu, inputs, without = shared_data / "cmu", tmp_path / "in", tmp_path / "without"
    for folder in (inputs / "07", without / "07"):
        folder.mkdir(parents=True)
        for name in ("07.asf", "07_02.amc"):
            shutil.copy(cmu / "07" / name, folder)
    (inputs / "09").mkdir()
    shutil.copy(cmu / "09" / "09.asf", inputs / "09")
    (inputs / "09" / "09_01.amc").write_text(root_at_the_limit(cmu / "09" / "09_01.amc"))
    archive, alone = tmp_path / "db.mcz", tmp_path / "alone.mcz"

    result = run("compress", inputs, "-o", archive, "-c", "subject", "--skip-bad", "--json", "-j", jobs)
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    [entry] = summary["skipped"]
    assert entry["path"] == "09/09_01.amc" and "its decoded values would pass" in entry["error"]
    assert result.stderr.splitlines() == [f"mcz: warning: skipped 09/09_01.amc: {entry['error']}"]
    assert summary["clips"] == 1

    assert run("compress", without, "-o", alone, "-c", "subject", "-j", jobs, "-q").exit_code == 0
    with mcz_module.ArchiveReader(archive) as left_out, mcz_module.ArchiveReader(alone) as never_there:
        assert left_out.names() == never_there.names()
        for name in left_out.names():
            assert name == "meta" or left_out.read(name) == never_there.read(name), name
    with Archive(archive) as left_out, Archive(alone) as never_there:
        meta = dict(left_out.meta)
        assert meta.pop("skipped") == summary["skipped"]
        assert meta == never_there.meta


def test_a_clip_left_out_at_coding_leaves_its_class_as_if_it_never_was(shared_data, tmp_path, monkeypatch):
    """A refused clip whose class keeps other clips: the class's poses are summed again without it,
    and the pooled classes, bases and streams are those of the inputs without it. (No real clip is
    refused beside others of its class cheaply, so the refusal is made for 09_02 here.)"""
    from mocapzip import archive
    from mocapzip.ratecontrol import encode
    from mocapzip.ratecontrol.max_error import TargetError

    cmu, inputs, without = shared_data / "cmu", tmp_path / "in", tmp_path / "without"
    for folder, names in ((inputs, ["09_02.amc", "09_03.amc"]), (without, ["09_03.amc"])):
        (folder / "07").mkdir(parents=True)
        (folder / "09").mkdir()
        for name in ("07.asf", "07_02.amc"):
            shutil.copy(cmu / "07" / name, folder / "07")
        for name in ["09.asf", *names]:
            shutil.copy(cmu / "09" / name, folder / "09")
    real = encode.achieved

    def refusing(clip, check, bounds):
        if clip.source.relpath == "09/09_02.amc":
            raise TargetError("no coding holds it (made so by the test)", clip.source.motion)
        return real(clip, check, bounds)

    monkeypatch.setattr(encode, "achieved", refusing)
    with pytest.warns(UserWarning, match="skipped 09/09_02.amc: .*made so by the test"):
        summary = archive.compress([inputs], tmp_path / "db.mcz", archive.Settings(), skip_bad=True)
    assert [entry["path"] for entry in summary["skipped"]] == ["09/09_02.amc"] and summary["clips"] == 2
    archive.compress([without], tmp_path / "alone.mcz", archive.Settings())
    with mcz_module.ArchiveReader(tmp_path / "db.mcz") as left_out, \
            mcz_module.ArchiveReader(tmp_path / "alone.mcz") as never_there:
        assert left_out.names() == never_there.names()
        for name in left_out.names():
            assert name == "meta" or left_out.read(name) == never_there.read(name), name
    with Archive(tmp_path / "db.mcz") as left_out, Archive(tmp_path / "alone.mcz") as never_there:
        assert [c["name"] for c in left_out.meta["classes"]] == ["pooled"]  # 07 and 09 share a basis
        meta = dict(left_out.meta)
        assert meta.pop("skipped") == summary["skipped"]
        assert meta == never_there.meta


def test_without_skip_bad_the_first_bad_clip_stops_the_run(mixed, tmp_path):
    root, cases, good = mixed
    out = tmp_path / "out"
    out.mkdir()
    line = error_line(run("compress", root / "value_nan", good, "-o", out / "db.mcz", "--lossless"))
    assert re.search(names(cases["value_nan"]), line)
    assert os.listdir(out) == []


@pytest.mark.parametrize("row, problem", [
    ("09_01.amc," + "x" * 5000, "a field of 5,000 characters, longer than the 4,096 a clip path or class name may have"),
    ("x" * 200_000 + ",walk", "not a valid CSV table: field larger than field limit (131072)"),
])
def test_bad_class_table_is_refused_in_one_line(shared_data, tmp_path, row, problem):
    """-c FILE.csv: a field longer than a path may be, or any csv error, names the table and line."""
    table = tmp_path / "classes.csv"
    table.write_text(f"09_02.amc,run\n{row}\n")
    clip = shared_data / hostile_inputs.SUBJECT / hostile_inputs.AMC_NAME
    line = error_line(run("compress", clip, "-c", table, "-o", tmp_path / "db.mcz", "--lossless"))
    assert line == f"mcz: error: {table}:2: {problem}"


def test_full_disk_during_compress_leaves_nothing(shared_data, tmp_path, monkeypatch):
    """HDF5 reports ENOSPC in several lines naming the temporary file; the user sees one line naming OUTPUT."""
    out = tmp_path / "out"
    out.mkdir()
    seen = []

    def full_disk(dataset, values):
        seen.extend(n for n in os.listdir(out) if n.startswith(".db.mcz.tmp-"))
        raise OSError(errno.ENOSPC, "Can't synchronously write data (file write failed: time = ...\n, "
                                    "filename = '.db.mcz.tmp-0', errno = 28, error message = 'No space left on device')")

    monkeypatch.setattr(mcz_module, "_write_payload", full_disk)
    result = run("compress", shared_data / "cmu" / "09" / "09_01.amc", "-o", out / "db.mcz", "--lossless", "-q")
    assert seen, "the temporary archive existed when the disk filled"
    assert error_line(result) == f"mcz: error: {out / 'db.mcz'}: cannot write the archive: No space left on device"
    assert os.listdir(out) == []


def test_full_disk_during_decompress_leaves_no_half_file(tmp_path, monkeypatch):
    reference = tmp_path / "reference"
    assert run("decompress", GOLDEN_LOSSLESS, "-o", reference, "-q").exit_code == 0
    with Archive(GOLDEN_LOSSLESS) as archive:
        first, second = list(archive.files)[:2]  # the order decompress writes in
    real_write, files = os.write, []

    def full_on_second_file(fd, data):
        inode = os.fstat(fd).st_ino  # descriptors are reused from file to file; inodes are not
        if inode not in files:
            files.append(inode)
        if len(files) < 2:
            return real_write(fd, data)
        real_write(fd, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # as a full disk raises it: no file name

    monkeypatch.setattr(os, "write", full_on_second_file)
    out = tmp_path / "out"
    line = error_line(run("decompress", GOLDEN_LOSSLESS, "-o", out, "-q"))
    assert line == f"mcz: error: {out / second}: No space left on device"
    left = {p.name: p.read_bytes() for p in out.iterdir()}
    assert list(left) == [first]  # the file completed before; no temp file
    assert left == {name: (reference / name).read_bytes() for name in left}


@pytest.mark.parametrize("name", ["\uff11\uff12\uff13", "\u0661\u0662\u0663", "\u00b2"])
def test_a_bone_named_with_digits_other_than_ascii_compresses(shared_data, tmp_path, name):
    """An AMC line is a frame number only if it is ASCII digits (formats.amc); meta's rule said
    `str.isdigit()`, so these bones, which every reader takes, made compress blame its archive."""
    folder = tmp_path / "in"
    folder.mkdir()
    for file in ("09.asf", "09_01.amc"):
        text = (shared_data / "cmu" / "09" / file).read_text(encoding="latin-1")
        (folder / file).write_text(re.sub(r"\blfemur\b", name, text), encoding="utf-8")
    for flags in ([], ["--lossless"]):
        assert run("compress", folder, "-o", tmp_path / "db.mcz", "-f", "-q", *flags).exit_code == 0
        assert run("decompress", tmp_path / "db.mcz", "-o", tmp_path / "back", "-f", "-q").exit_code == 0
        assert f"\n{name} ".encode() in (tmp_path / "back" / "09_01.amc").read_bytes()

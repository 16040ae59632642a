"""`mcz remove` and `mcz append` (issue 43): every clip kept decodes to the same bytes and keeps its
stored errors, the new clips meet their bounds against their sources, the result passes `mcz test`,
and a run that dies leaves the old archive as it was and no file beside it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip.archive import Archive, Settings, compress, decompress
from mocapzip.archive import edit
from mocapzip.cli.main import main
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import FORMAT_VERSION
from tests.test_max_error import joint_errors

ORIGINAL = {"09": ["09_01.amc", "09_02.amc", "09_03.amc"], "93": ["93_05.amc"]}
NEW = {"09": ["09_05.amc", "09_06-run.amc"]}
# too few frames for "auto" to keep priors: forced, so they are tested; every joint within 5 cm: patches
PRIMED = Settings(coefficient_coder="primed", max_error_cm=5.0)


def run(*args):
    return CliRunner().invoke(main, [os.fspath(a) for a in args])


def linked(folder: Path, shared_data: Path, subjects: dict) -> Path:
    """A folder of links to the named CMU clips and their subjects' ASF files, as subject/clip."""
    for subject, names in subjects.items():
        (folder / subject).mkdir(parents=True)
        for name in [*names, f"{subject}.asf"]:
            (folder / subject / name).symlink_to(shared_data / "cmu" / subject / name)
    return folder


def files(archive: Path, out: Path) -> dict[str, bytes]:
    """Every file a full decompress of `archive` writes, by path."""
    decompress(archive, out)
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in out.rglob("*") if p.is_file()}


def rows(archive: Path) -> dict[str, dict]:
    with Archive(archive) as opened:
        opened.verify()  # `mcz test`
        return {row["path"]: row for row in opened.clips}


@pytest.fixture(scope="module")
def original(tmp_path_factory, shared_data):
    folder = tmp_path_factory.mktemp("edit")
    compress([linked(folder / "src", shared_data, ORIGINAL)], folder / "a.mcz", PRIMED, jobs=2)
    return folder / "a.mcz"


@pytest.fixture(scope="module")
def appended(original, tmp_path_factory, shared_data):
    folder = tmp_path_factory.mktemp("append")
    new = linked(folder / "new", shared_data, NEW)
    assert run("append", original, new / "09", "--under", "09", "-o", folder / "b.mcz", "-q", "-j", "2").exit_code == 0
    return folder / "b.mcz", new


def test_remove_keeps_every_other_clip_byte_for_byte(original, tmp_path):
    smaller = tmp_path / "smaller.mcz"
    result = run("remove", original, "09_02*", "-o", smaller)
    assert result.exit_code == 0, result.stderr
    assert result.stderr == f"1 clip removed, 3 clips left -> {smaller} ({smaller.stat().st_size:,} bytes)\n"
    before, after = files(original, tmp_path / "a"), files(smaller, tmp_path / "b")
    assert after == {path: data for path, data in before.items() if path != "09/09_02.amc"}
    old, new = rows(original), rows(smaller)
    assert "patched_frames" in new["93/93_05.amc"]  # a renumbered patch stream: clip 3, then 2
    for path, row in new.items():  # the stored errors, and all else, but for the renumbered indices
        assert row == old[path]
    with Archive(original) as a, Archive(smaller) as b:
        assert b.settings.coefficient_coder == "primed" and b.stream("priors") == a.stream("priors")


def test_remove_drops_a_skeleton_no_clip_uses(original, tmp_path):
    """09's skeleton goes: 93's, skeleton 1, becomes skeleton 0."""
    smaller = tmp_path / "smaller.mcz"
    assert run("remove", original, "09/*", "-o", smaller, "-q").exit_code == 0
    with Archive(smaller) as opened:
        assert [entry["name"] for entry in opened.meta["skeletons"]] == ["93.asf"]
        assert [(c["clips"], c["frames"]) for c in opened.meta["classes"]] == [(1, opened.clips[0]["frames"])]
    before = files(original, tmp_path / "a")
    assert files(smaller, tmp_path / "b") == {path: data for path, data in before.items() if path.startswith("93/")}


def test_append_keeps_the_old_clips_and_holds_the_new_to_their_bounds(original, appended, tmp_path, shared_data):
    bigger, new = appended
    before, after = files(original, tmp_path / "a"), files(bigger, tmp_path / "b")
    assert {path: after[path] for path in before} == before
    old, both = rows(original), rows(bigger)
    assert {path: both[path] for path in old} == old
    with Archive(bigger) as opened:
        settings = opened.settings
        # coded in class 09 the new clips measure more bytes than in a class of their own with its basis
        assert [c["clips"] for c in opened.meta["classes"]] == [4, 2]
        assert len(opened.meta["skeletons"]) == 2  # 09.asf once: the same entry and text
    for name in NEW["09"]:
        row, source = both[f"09/{name}"], shared_data / "cmu/09" / name
        errors = joint_errors(source, tmp_path / "b/09" / name, shared_data / "cmu/09/09.asf")
        assert errors.mean() <= settings.error_cm and errors.max() <= settings.max_error_cm
        assert errors.mean() == pytest.approx(row["error_cm"], abs=1e-6)  # the row says what the file achieves
        assert errors.max() == pytest.approx(row["max_error_cm"], abs=1e-6)


def test_a_clip_a_stored_class_explains_is_coded_in_that_class(original, tmp_path, shared_data):
    """09_02 appended again, under another folder: class 09's basis was fitted to it, so coded there
    it takes fewer bytes than in a class of its own, with that class's basis; no class is added."""
    again = linked(tmp_path / "new", shared_data, {"09": ["09_02.amc"]})
    bigger = tmp_path / "b.mcz"
    summary = mocapzip.append(original, again / "09", bigger, under="again", jobs=2, progress=False)
    assert summary["added"] == summary["in_stored_classes"] == ["again/09_02.amc"]
    before, after = files(original, tmp_path / "a"), files(bigger, tmp_path / "b")
    assert {path: after[path] for path in before} == before
    old, both = rows(original), rows(bigger)
    assert {path: both[path] for path in old} == old
    with Archive(original) as a, Archive(bigger) as b:
        counts = [c["clips"] for c in a.meta["classes"]]
        counts[old["09/09_02.amc"]["class"]] += 1
        assert [c["clips"] for c in b.meta["classes"]] == counts  # no class added
        assert [c["name"] for c in b.meta["classes"]] == [c["name"] for c in a.meta["classes"]]
        assert all(b.stream(f"class/{k:04d}") == a.stream(f"class/{k:04d}") for k in range(len(counts)))
    row = both["again/09_02.amc"]
    assert row["class"] == old["09/09_02.amc"]["class"]
    assert run("remove", bigger, "again/*", "-o", tmp_path / "again.mcz", "-q").exit_code == 0
    assert (tmp_path / "again.mcz").read_bytes() == original.read_bytes()  # its class recounted as it was
    source = shared_data / "cmu/09"
    errors = joint_errors(source / "09_02.amc", tmp_path / "b/again/09_02.amc", source / "09.asf")
    assert errors.mean() <= PRIMED.error_cm and errors.max() <= PRIMED.max_error_cm
    assert errors.mean() == pytest.approx(row["error_cm"], abs=1e-6)
    assert errors.max() == pytest.approx(row["max_error_cm"], abs=1e-6)


def test_a_clip_no_stored_class_fits_gets_a_class_of_its_own(original, tmp_path, shared_data):
    """A BVH clip of another skeleton, whose poses no stored basis has the width of: a new class."""
    new, name = tmp_path / "new", "dataset-1_run_normal_001.bvh"
    new.mkdir()
    (new / name).symlink_to(shared_data / "bvh-bandai" / name)
    bigger = tmp_path / "b.mcz"
    summary = mocapzip.append(original, new, bigger, jobs=2, progress=False)
    assert summary["added"] == [name] and summary["in_stored_classes"] == []
    with Archive(original) as a, Archive(bigger) as b:
        classes = len(a.meta["classes"])
        assert [c["clips"] for c in b.meta["classes"]] == [c["clips"] for c in a.meta["classes"]] + [1]
    assert rows(bigger)[name]["class"] == classes
    before, after = files(original, tmp_path / "a"), files(bigger, tmp_path / "b")
    assert {path: after[path] for path in before} == before


def test_segmented_takes_are_appended_in_classes_of_their_own(shared_data, tmp_path):
    """--segment: a take's segments are joined across their classes, so none goes to a stored one,
    even the take its class was fitted to."""
    archive, bigger = tmp_path / "seg.mcz", tmp_path / "b.mcz"
    compress([linked(tmp_path / "src", shared_data, {"09": ["09_02.amc"]})], archive, Settings(segment=True), jobs=2)
    again = linked(tmp_path / "new", shared_data, {"09": ["09_02.amc"]})
    summary = mocapzip.append(archive, again / "09", bigger, under="again", jobs=2, progress=False)
    assert summary["in_stored_classes"] == []
    with Archive(archive) as a, Archive(bigger) as b:
        assert len(b.meta["classes"]) == 2 * len(a.meta["classes"])


def test_appended_clips_decode_as_compressed_alone(appended, tmp_path):
    """Coded again from the archive's priors, the new clips' coefficients are those compress gives them."""
    bigger, new = appended
    compress([new], tmp_path / "alone.mcz", PRIMED, jobs=2)
    alone = files(tmp_path / "alone.mcz", tmp_path / "alone")
    assert alone == {path: data for path, data in files(bigger, tmp_path / "b").items() if path in alone}


def test_removing_what_was_appended_gives_the_archive_back(original, appended, tmp_path):
    bigger, _ = appended
    again = tmp_path / "again.mcz"
    assert run("remove", bigger, "09_05.amc", "09_06-run.amc", "-o", again, "-q").exit_code == 0
    assert again.read_bytes() == original.read_bytes()


def test_lossless_remove_and_append(shared_data, tmp_path):
    archive, out = tmp_path / "lossless.mcz", tmp_path / "out"
    compress([linked(tmp_path / "src", shared_data, {"09": ["09_01.amc", "09_02.amc"]})], archive,
             Settings(lossless=True))
    assert run("remove", archive, "09_01.amc", "-f", "-q").exit_code == 0
    new = linked(tmp_path / "new", shared_data, {"93": ["93_04.amc"]})
    assert run("append", archive, new, "-f", "-q").exit_code == 0
    written = files(archive, out)
    assert set(rows(archive)) == {"09/09_02.amc", "93/93_04.amc"}
    for path in rows(archive):
        assert written[path] == (shared_data / "cmu" / path).read_bytes()


def _listing(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def test_an_append_interrupted_leaves_the_archive_as_it_was(original, tmp_path, shared_data, monkeypatch):
    folder = tmp_path / "db"
    folder.mkdir()
    archive = folder / "a.mcz"
    archive.write_bytes(original.read_bytes())
    new = linked(tmp_path / "new", shared_data, NEW)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(edit, "code_classes", interrupted)
    result = run("append", archive, new, "-f", "-q")
    assert result.exit_code == 1 and "interrupted" in result.stderr
    assert _listing(folder) == {"a.mcz": original.read_bytes()}


KILLED_CHILD = r"""
import os, signal, sys
from mocapzip.archive import edit
from mocapzip.formats import mcz
from mocapzip.cli.main import main

def killed(*args, **kwargs):  # SIGKILL, as the OOM killer sends it: no clean-up runs
    os.kill(os.getpid(), signal.SIGKILL)

module, name = {"coding": (edit, "code_classes"), "writing": (mcz, "_write_payload")}[sys.argv[1]]
setattr(module, name, killed)
main(sys.argv[2:])
"""


@pytest.mark.parametrize("when", ["coding", "writing"])
def test_an_append_killed_leaves_the_archive_as_it_was(original, tmp_path, shared_data, when):
    """Killed while the new clips are coded, the new archive's streams wait in an unnamed file: nothing
    is left beside the archive. Killed while the new archive is written, its temporary file is left
    (docs/editing.md), never in the archive's place, and the next write to the archive removes it."""
    folder = tmp_path / "db"
    folder.mkdir()
    archive = folder / "a.mcz"
    archive.write_bytes(original.read_bytes())
    new = linked(tmp_path / "new", shared_data, NEW)
    child = subprocess.Popen([sys.executable, "-c", KILLED_CHILD, when, "append", os.fspath(archive), os.fspath(new),
                              "-f", "-q", "-j", "1"], env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    assert child.wait(timeout=300) == -signal.SIGKILL
    left = _listing(folder)
    assert left.pop("a.mcz") == original.read_bytes()
    assert [name.startswith(f".a.mcz.tmp-{child.pid}-") for name in left] == ([] if when == "coding" else [True])
    assert run("remove", archive, "09_01.amc", "-f", "-q").exit_code == 0
    assert list(_listing(folder)) == ["a.mcz"]


@pytest.mark.parametrize("arguments, said", [
    (["remove", "{a}", "nothing*", "-o", "{d}/x.mcz"], "mcz: error: {a}: no clip matches nothing*"),
    (["remove", "{a}", "*", "-o", "{d}/x.mcz"], "mcz: error: {a}: * would remove every clip: delete the archive instead"),
    (["remove", "{a}", "09_01.amc", "-o", "{a}"], "mcz: error: {a}: already exists (use -f/--force to overwrite)"),
    (["append", "{a}", "{d}/new/09", "--under", "09", "-o", "{d}/x.mcz"],
     "mcz: error: {d}/new/09/09_01.amc: the archive already holds a clip stored as '09/09_01.amc' (mcz remove it first)"),
    (["remove", "{old}", "*", "-o", "{d}/x.mcz"],
     "mcz: error: {old}: an archive of format 11: only format {newest} is edited (decompress it and compress it again)"),
])
def test_refusals_are_one_line(original, tmp_path, shared_data, arguments, said):
    linked(tmp_path / "new", shared_data, {"09": ["09_01.amc"]})
    names = {"a": original, "d": tmp_path, "old": Path(__file__).parent / "golden" / "lossy_v11.mcz",
             "newest": FORMAT_VERSION}
    before = original.read_bytes()
    result = run(*[a.format(**names) for a in arguments])
    assert result.exit_code == 1
    assert result.stderr == said.format(**names) + "\n"
    assert original.read_bytes() == before and not (tmp_path / "x.mcz").exists()


def test_an_archive_edited_in_place_only_with_force(original, tmp_path):
    result = run("remove", original, "09_01.amc")
    assert result.exit_code == 2
    assert result.stderr == ("mcz remove: name the new archive with -o, or give -f to replace ARCHIVE in place "
                             "(see mcz remove --help)\n")


def test_the_api_edits_as_the_command_line(original, appended, tmp_path):
    """`mocapzip.remove` and `mocapzip.append` write the archives `mcz remove` and `mcz append` write."""
    bigger, new = appended
    summary = mocapzip.append(original, new / "09", tmp_path / "b.mcz", under="09", jobs=2, progress=False)
    assert summary["added"] == ["09/09_05.amc", "09/09_06-run.amc"] and summary["clips"] == 6
    assert (tmp_path / "b.mcz").read_bytes() == bigger.read_bytes()
    assert run("remove", original, "09_02*", "93_05.amc", "-o", tmp_path / "cli.mcz", "-q").exit_code == 0
    summary = mocapzip.remove(original, ["09_02*", "93_05.amc"], tmp_path / "api.mcz")
    assert summary["removed"] == ["09/09_02.amc", "93/93_05.amc"] and summary["clips"] == 2
    assert summary["output_bytes"] == (tmp_path / "api.mcz").stat().st_size
    assert (tmp_path / "api.mcz").read_bytes() == (tmp_path / "cli.mcz").read_bytes()
    copy = tmp_path / "copy.mcz"
    copy.write_bytes(original.read_bytes())
    assert mocapzip.remove(copy, "09_02.amc", force=True)["output"] == os.fspath(copy)  # in place
    assert set(rows(copy)) == {"09/09_01.amc", "09/09_03.amc", "93/93_05.amc"}


IN_PLACE = "already exists: give output= for a new archive, or force=True"


@pytest.mark.parametrize("edit_call, error", [
    (lambda a, d: mocapzip.remove(a, "09_01.amc"), IN_PLACE),
    (lambda a, d: mocapzip.append(a, d / "new", progress=False), IN_PLACE),
    (lambda a, d: mocapzip.remove(a, [], d / "x.mcz"), "remove() takes one or more patterns (str), got []"),
    (lambda a, d: mocapzip.remove(a, "nothing*", d / "x.mcz"), "no clip matches nothing*"),
    (lambda a, d: mocapzip.append(a, d / "new", d / "x.mcz", under="../x", progress=False),
     "under must be a relative folder without '.' or '..', got '../x'"),
])
def test_the_api_refuses_an_edit_before_writing(original, tmp_path, shared_data, edit_call, error):
    linked(tmp_path / "new", shared_data, {"09": ["09_04.amc"]})
    before = original.read_bytes()
    with pytest.raises((OSError, TypeError, ValueError, MocapFormatError)) as raised:
        edit_call(original, tmp_path)
    assert error in str(raised.value)
    assert original.read_bytes() == before and not (tmp_path / "x.mcz").exists()


def test_an_api_append_interrupted_leaves_the_archive_as_it_was(original, tmp_path, shared_data, monkeypatch):
    folder = tmp_path / "db"
    folder.mkdir()
    archive = folder / "a.mcz"
    archive.write_bytes(original.read_bytes())

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(edit, "code_classes", interrupted)
    with pytest.raises(KeyboardInterrupt):
        mocapzip.append(archive, linked(tmp_path / "new", shared_data, NEW), force=True, progress=False)
    assert _listing(folder) == {"a.mcz": original.read_bytes()}

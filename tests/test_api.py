"""The Python API (mocapzip/api.py, docs/api.md): its examples run, one clip is read alone, and
its defaults and errors are the command line's."""

from __future__ import annotations

import doctest
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip.cli.main import main
from mocapzip.formats.amc import parse_amc
from mocapzip.formats.mcz import ArchiveReader

DOCS = Path(__file__).resolve().parents[1] / "docs" / "api.md"
GOLDEN_LOSSY = Path(__file__).parent / "golden" / "lossy_v7.mcz"


def test_the_examples_in_docs_api_md_run(shared_data, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data").symlink_to(shared_data)
    result = doctest.testfile(str(DOCS), module_relative=False, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and result.attempted >= 20, result


def test_import_mocapzip_stays_cheap_and_changes_nothing_in_the_process():
    code = ("import os, sys; hook, env = sys.excepthook, dict(os.environ); import mocapzip; "
            "assert 'numpy' not in sys.modules; mocapzip.open; assert 'numpy' in sys.modules; "
            "assert sys.excepthook is hook and dict(os.environ) == env and 'mocapzip.cli' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
    # and `mcz --help` imports neither NumPy nor the API
    code = "import sys, mocapzip.cli.main; assert not {'numpy', 'mocapzip.api'} & set(sys.modules)"
    subprocess.run([sys.executable, "-c", code], check=True)
    for name in [*mocapzip.__all__, "open"]:
        assert getattr(mocapzip, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        mocapzip.nothing


def test_reading_one_clip_reads_only_its_own_streams(monkeypatch):
    read = []
    original = ArchiveReader.read
    monkeypatch.setattr(ArchiveReader, "read", lambda self, name: read.append(name) or original(self, name))
    with mocapzip.open(GOLDEN_LOSSY) as archive:
        assert set(read) == {"meta"}  # the skeletons too are read when first needed
        read.clear()
        clip = archive["64_01.amc"]
        assert read == []  # nothing is decoded until asked for
        clip.channels
        assert set(read) == {"skeletons", "clip/00001", "patch/00001", "class/0000", "priors"}
        read.clear()
        clip.positions(), archive["64_01.amc"].channels, list(archive)[1].positions()
        assert read == []  # decoded once, then kept


def test_clips_by_path_and_position():
    with mocapzip.open(GOLDEN_LOSSY) as archive:
        assert [clip.path for clip in archive] == archive.paths == ["09_01.amc", "64_01.amc"]
        assert archive[-1].path == archive[1].path == "64_01.amc"
        report = json.loads(CliRunner().invoke(main, ["info", "--json", str(GOLDEN_LOSSY)]).output)
        assert [tuple(clip.error) for clip in archive] == [
            (row["error_cm"], row["p99_error_cm"], row["max_error_cm"], row.get("max_vertex_error_cm"))
            for row in report["clips"]]
        with pytest.raises(KeyError, match="no clip '10_01.amc'"):
            archive["10_01.amc"]
        with pytest.raises(IndexError):
            archive[2]
        with pytest.raises(TypeError, match="by path .* or position"):
            archive[1.0]


def test_compress_takes_the_command_line_defaults(shared_data, tmp_path):
    clip = shared_data / "cmu" / "09" / "09_01.amc"
    asf = clip.with_name("09.asf")
    summary = mocapzip.compress([asf, clip], tmp_path / "a.mcz", error=2.0)
    with mocapzip.open(tmp_path / "a.mcz") as archive:
        assert archive.settings.error_cm == 2.0 and archive.settings.max_error_cm == 10.0  # 5 x error
        assert archive[0].error.mean_cm == summary["largest_mean_error_cm"] <= 2.0
    mocapzip.compress([asf, clip], tmp_path / "a.mcz", error=2.0, max_error=None, representation="positions",
                      force=True)
    with mocapzip.open(tmp_path / "a.mcz") as archive:
        assert archive.settings.max_error_cm is None and archive.settings.representation == "positions"
    with pytest.raises(mocapzip.SettingsError, match="representation"):
        mocapzip.compress([asf, clip], tmp_path / "b.mcz", representation="quaternions")
    assert not (tmp_path / "b.mcz").exists()


def test_a_closed_archive_keeps_what_was_decoded_and_refuses_more():
    archive = mocapzip.open(GOLDEN_LOSSY)
    with archive:
        first = archive[0]
        values = first.channels.copy()
    assert np.array_equal(first.channels, values) and first.positions().shape == (148, 31, 3)
    with pytest.raises(ValueError, match="closed archive"):
        archive[1]
    with pytest.raises(ValueError, match="read-only"):
        first.channels[0, 0] = 1.0


def test_a_lossless_archive_reports_zero_error_and_exact_values(shared_data):
    with mocapzip.open(GOLDEN_LOSSY.with_name("lossless_v1.mcz")) as archive:
        clip = archive[0]
        assert clip.error == mocapzip.ClipFidelity(0.0, 0.0, 0.0, 0.0)
        source = mocapzip.read_amc(shared_data / "cmu" / "09" / clip.path.split("/")[-1])
        assert np.array_equal(clip.channels, source.values)


def test_shell_error_against_the_source_is_made_of_its_joint_and_shell_parts(shared_data):
    # A vertex s cm along a bone's axis moves by d + s a (d: the bone origin's move, a: its axis's).
    # At s = 0 the worst is the worst joint: every joint is some bone's origin. And as
    # |d + 2 s a| <= 2 |d + s a| + |d|, each bone's error at 6 cm is bounded by those at 3 and 0.
    with mocapzip.open(GOLDEN_LOSSY) as archive:
        for clip in archive:
            path = shared_data / "cmu" / clip.path.split("_")[0] / clip.path
            shell, joints, double = (clip.shell_error(path, shell_cm) for shell_cm in (3.0, 0.0, 6.0))
            assert shell.errors.shape == (clip.frames, len(clip.joint_names) + 7)  # 7 end bones: toes, head, hands
            assert abs(joints.worst - clip.error.max_cm) < 1e-5
            assert np.all(double.errors <= 2 * shell.errors + joints.errors + 1e-9)
            assert np.array_equal(clip.shell_error(mocapzip.read_amc(path, clip.skeleton)).errors, shell.errors)
        with pytest.raises(mocapzip.MocapFormatError,
                           match="09_01.amc: 148 frames of 31 joints, the archive's 64_01.amc has 448 of 31: not its"):
            archive["64_01.amc"].shell_error(shared_data / "cmu" / "09" / "09_01.amc")
    with mocapzip.open(GOLDEN_LOSSY.with_name("lossless_v1.mcz")) as archive:
        clip = archive[0]
        assert clip.shell_error(shared_data / "cmu" / "09" / clip.path.split("/")[-1]).worst == 0.0


def test_mcz_test_against_the_source_folder_prints_each_clips_worst_vertex(shared_data, tmp_path):
    for name in ("09_01.amc", "64_01.amc"):  # the golden archive's clips, compressed from one folder
        (tmp_path / name).symlink_to(shared_data / "cmu" / name[:2] / name)
    result = CliRunner().invoke(main, ["test", str(GOLDEN_LOSSY), "--against", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert "worst vertex (ACL's metric, 3 cm shell)" in lines[0]
    with mocapzip.open(GOLDEN_LOSSY) as archive:
        for line, clip in zip(lines[1:], archive, strict=True):
            shell = clip.shell_error(tmp_path / clip.path)
            assert line.split()[:5] == [clip.path, f"{clip.error.mean_cm:.3f}", f"{clip.error.p99_cm:.3f}",
                                        f"{clip.error.max_cm:.3f}", f"{shell.worst:.3f}"]
            assert line.endswith(f"{shell.worst_bone}, frame {shell.worst_frame}")
    result = CliRunner().invoke(main, ["test", str(GOLDEN_LOSSY), "--against", str(tmp_path), "--shell-cm", "0", "-q"])
    for line in result.output.splitlines()[1:]:  # no shell: the worst vertex is the worst joint
        assert line.split()[3] == line.split()[4]
    (tmp_path / "64_01.amc").unlink()
    result = CliRunner().invoke(main, ["test", str(GOLDEN_LOSSY), "--against", str(tmp_path), "-q"])
    assert result.exit_code == 1 and "64_01.amc: No such file" in result.output


@pytest.mark.parametrize("options, message", [
    ({"error_cm": 2.0}, "give error_cm as error="),
    ({"max_error": "none"}, "max_error must be a number of cm or None"),
    ({"lossless": True, "max_error": 3.0}, "max_error has no meaning with lossless=True"),
    ({"colour": "red"}, "compress.. takes no option 'colour'"),
    ({"error": 0}, "error_cm must be from 1e-06 to 1e\\+06 cm"),
])
def test_compress_refuses_options_it_cannot_honour_before_reading_anything(tmp_path, options, message):
    with pytest.raises(mocapzip.SettingsError, match=message):
        mocapzip.compress(tmp_path / "no such folder", tmp_path / "a.mcz", **options)
    assert list(tmp_path.iterdir()) == []


def test_compress_runs_on_one_blas_thread_in_every_process_and_gives_the_caller_its_own_back(
        shared_data, tmp_path, monkeypatch):
    """The API's caller imported numpy first, with no BLAS thread count in its environment, so its BLAS
    runs a thread per core; mcz's work (here and in its forked workers) gets one, as from the command
    line (`parallel.one_blas_thread`)."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from mocapzip.inputs.clip import LoadedClip
    from mocapzip.defaults import BLAS_THREAD_VARIABLES

    def blas_threads() -> int:
        return max((lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"), default=0)

    for name in BLAS_THREAD_VARIABLES:  # tests/conftest.py set them before numpy loaded; this caller has none
        monkeypatch.delenv(name, raising=False)

    seen = tmp_path / "seen"
    error = LoadedClip.error

    def error_noting_threads(self, *args, **kwargs):
        with open(seen, "a") as out:
            out.write(f"{os.getpid()} {blas_threads()}\n")
        return error(self, *args, **kwargs)

    monkeypatch.setattr(LoadedClip, "error", error_noting_threads)
    with threadpool_limits(limits=2, user_api="blas"):  # the caller's
        assert blas_threads() == 2
        mocapzip.compress([shared_data / "cmu" / "07" / name for name in ("07.asf", "07_01.amc", "07_02.amc")],
                          tmp_path / "a.mcz", jobs=2)
        assert blas_threads() == 2
    records = [line.split() for line in seen.read_text().splitlines()]
    assert {threads for _, threads in records} == {"1"}
    assert {pid for pid, _ in records} - {str(os.getpid())}, "no worker scored a clip"


def test_an_explicit_blas_thread_count_in_the_environment_wins(monkeypatch):
    """`OPENBLAS_NUM_THREADS` (or OMP_, MKL_) set by the caller is theirs to choose: mcz leaves BLAS as it is."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from mocapzip.parallel import one_blas_thread

    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    seen = one_blas_thread(lambda: [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"])
    with threadpool_limits(limits=2, user_api="blas"):
        assert set(seen()) == {2}
    monkeypatch.delenv("OPENBLAS_NUM_THREADS")
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(name, raising=False)
    with threadpool_limits(limits=2, user_api="blas"):
        assert set(seen()) == {1}


def test_clips_read_without_text_are_the_values_of_the_files_decompress_writes():
    for name in ("lossy_v7.mcz", "lossless_v1.mcz"):
        with mocapzip.open(GOLDEN_LOSSY.with_name(name)) as archive:
            for clip in archive:
                written = parse_amc(archive._archive.file_bytes("motion", clip.index), clip.path)
                assert np.array_equal(clip.channels, written.values) and clip.channels.dtype == np.float64
                assert len(clip.channel_labels) == clip.channels.shape[1]


def test_as_printed_is_printing_and_reading_back():
    from mocapzip.formats.text import as_printed

    values = np.random.default_rng(0).normal(0, 50, 20000) * 10.0 ** np.random.default_rng(1).integers(-18, 6, 20000)
    values = np.concatenate([values, [0.0, -0.0, 0.5, 2.5, 999999.5, 9.9999995, 1e-30]])
    for notation, digits in (("g", 6), ("g", 15), ("f", 6), ("f", 2)):
        expected = np.array([float(f"%.{digits}{notation}" % v) for v in values])
        assert np.array_equal(as_printed(values, notation, digits).view(np.int64), expected.view(np.int64))


def test_the_archive_finds_clips_by_file_name_and_pattern(shared_data, tmp_path):
    for folder in ("a", "b"):
        (tmp_path / "in" / folder).mkdir(parents=True)
        for name in ("09.asf", "09_01.amc"):
            (tmp_path / "in" / folder / name).symlink_to(shared_data / "cmu" / "09" / name)
    (tmp_path / "in" / "b" / "09_02.amc").symlink_to(shared_data / "cmu" / "09" / "09_02.amc")
    mocapzip.compress(tmp_path / "in", tmp_path / "t.mcz", jobs=1, progress=False)
    with mocapzip.open(tmp_path / "t.mcz") as archive:
        assert archive.keys() == ["a/09_01.amc", "b/09_01.amc", "b/09_02.amc"]
        assert archive["09_02.amc"] is archive["b/09_02.amc"] and "09_02.amc" in archive
        assert "09_01.amc" not in archive
        with pytest.raises(KeyError, match=r"2 clips are called '09_01.amc' .*: give its path \(a/09_01.amc, b/09_01"):
            archive["09_01.amc"]
        with pytest.raises(KeyError, match="did you mean 'b/09_02.amc'"):
            archive["b/09_03.amc"]
        assert [clip.path for clip in archive.glob("09_0[2-9]*")] == ["b/09_02.amc"]
        assert [path for path, _ in archive.items()] == [clip.path for clip in archive.values()]
        clip = archive["09_02.amc"]
        part = clip[-10:]
        assert part.frames == 10 and np.array_equal(part.channels, clip.channels[-10:])
        assert part.motion.frame_numbers[0] == clip.motion.frame_numbers[-10]
        assert clip[5:2].frames == 0 and abs(clip.duration - clip.frames / clip.fps) < 1e-12
        with pytest.raises(TypeError, match="sliced by frames"):
            clip[::2]
        q = clip.rotations(np.float32)
        assert q.dtype == np.float32 and np.allclose(np.linalg.norm(q, axis=-1), 1, atol=1e-6)
        world = clip.transforms()
        assert np.allclose(world[..., :3, 3], clip.positions()) and np.allclose(world[..., 3, :], [0, 0, 0, 1])
    result = CliRunner().invoke(main, ["decompress", str(tmp_path / "t.mcz"), "-o", str(tmp_path / "out"),
                                       "--clip", "09_02*", "-q"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "out").rglob("*.amc")) == ["09_02.amc"]


def test_save_writes_its_own_format_byte_for_byte_and_converts(tmp_path):
    with mocapzip.open(GOLDEN_LOSSY) as archive:
        clip = archive[0]
        assert clip.save(tmp_path / "x.amc") == [str(tmp_path / "x.amc"), str(tmp_path / "x.asf")]
        assert (tmp_path / "x.amc").read_bytes() == archive._archive.file_bytes("motion", 0)
        clip.save(tmp_path / "x.bvh")
        back = mocapzip.read_bvh(tmp_path / "x.bvh")
        assert back.values.shape[0] == clip.frames
        with pytest.raises(FileExistsError):
            clip.save(tmp_path / "x.bvh")
        with pytest.raises(ValueError, match="writes .amc or .bvh"):
            clip.save(tmp_path / "x.txt")

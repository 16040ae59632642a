"""Hostile tensor, warp, plant and patch streams (issue 40, items 4 and 6).

The generated suite (tests/hostile_streams.py) changes one stream, or the meta that claims it, of
archives compressed from real clips, and runs `mcz test` on each in a child limited to 1 GiB of
address space and 60 seconds: each must be refused in one line naming its section, exit 1, or,
where the change leaves an archive the spec defines, decode as the reference decoder decodes it.
Before it, the faults the issue reported, each on the golden format-11 archive.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import hostile_archives
import hostile_streams
import reference_decoder
from mocapzip.archive import Archive
from mocapzip.cli.main import main
from mocapzip.formats.mcz import ArchiveError
from mocapzip.ratecontrol import tensor
from test_bvh_pipeline import linked
from test_reference_decoder import check_against_package

CASES = hostile_streams.cases()


def golden_with(edit, path: Path) -> Path:
    """The golden format-11 archive (hostile_archives.BASES["lossy_tensor"]) with `edit` made, at `path`."""
    hostile_archives.build(hostile_archives.Case("edited", "lossy_tensor", edit, ""), path)
    return path


def refused_in_one_line(archive: Path, section: str) -> None:
    """`mcz test ARCHIVE`, in a child limited to 1 GiB and 60 s, exits 1 with one line naming `section`."""
    result = hostile_archives.run_mcz("test", "-q", str(archive))
    lines = result.stderr.splitlines()
    assert result.returncode == 1 and not result.stdout and len(lines) == 1, result.stderr[-3000:]
    assert lines[0].startswith(f"mcz: error: {archive}: ") and section in lines[0], lines[0]


# --------------------------------------------------------------------------- item 4: a model's sizes


@pytest.mark.parametrize("k, sizes, ranks", [
    (2, [1 << 11, 1 << 14, 2, 4], [1 << 11, 1 << 11, 2, 4]),  # as reported: 71 M values, each matrix within its limits
    (1, [1 << 11, 1 << 14, 2], [1 << 11, 1 << 11, 2]),  # its class's one mode: 46 M values
], ids=["71M-values", "46M-values-of-one-mode"])
def test_a_5kb_tensor_model_claiming_tens_of_millions_of_values_is_refused_before_decoding(tmp_path, k, sizes,
                                                                                          ranks):
    """The check that a model fits its class ran after the whole model was decoded into float64:
    under 1 GiB, a traceback (`_ArrayMemoryError`). Now every size is checked first."""
    model = hostile_streams.model_blob(k, sizes, ranks, 0.5)
    archive = golden_with(hostile_archives._stream("tensor/0001", model), tmp_path / "bomb.mcz")
    assert archive.stat().st_size < 8000
    refused_in_one_line(archive, "tensor/0001: damaged (")


# --------------------------------------------------------------------------- item 6: what meta does not claim


@pytest.mark.parametrize("edit, message", [
    # the issue's: a copy of clip 1's patches as patch/00002 (clip 2, the BVH clip, has none)
    (hostile_archives._both(), None),
    (lambda meta, streams: streams.update({"patch/00002": streams["patch/00001"]}),
     "patch/00002: a stream that no part of meta claims"),
    (lambda meta, streams: streams.update({"plant/00002": streams["plant/00001"]}),
     "plant/00002: a stream that no part of meta claims"),
    (lambda meta, streams: streams.update({"warp/00002": streams["warp/00001"]}),  # clip 2's class is PCA
     "warp/00002: a stream that no part of meta claims"),
    (lambda meta, streams: streams.update({"tensor/0000": streams["tensor/0001"]}),  # class 0 is PCA
     "tensor/0000: a stream that no part of meta claims"),
    (lambda meta, streams: streams.update({"extra_root/00000": streams["extra_root/00002"]}),  # clip 0 is an AMC
     "extra_root/00000: a stream that no part of meta claims"),
    (lambda meta, streams: streams.update({"clip/00003": streams["clip/00002"]}),
     "clip/00003: a stream that no part of meta claims"),
    (hostile_archives._set("settings.plant_feet", False), "meta: clips[0].planted_stances: written only with "
                                                          "settings.plant_feet, which this archive has not"),
    (hostile_archives._both(hostile_archives._delete("settings.max_error_cm"),
                            hostile_archives._delete("settings.contact_error_cm")),
     "meta: clips[0].patched_frames: written only with settings.max_error_cm, contact_error_cm or vertex_error_cm"),
    (hostile_archives._delete("settings.repair_glitches"), "meta: clips[1].repaired: written only with "
                                                           "settings.repair_glitches"),
    (hostile_archives._set("clips.1.tensor_at", [0]), "meta: clips[1].tensor_at: clip 0's place in its class's grid"),
    (lambda meta, streams: meta["classes"][1]["levels"][0].append("35"),
     "meta: classes[1].levels: a grid of 3 places, 2 of them with a clip"),
], ids=["as-written", "patch", "plant", "warp", "tensor", "extra_root", "clip", "plant_feet-false",
        "patches-without-a-bound", "repaired-without-repair_glitches", "two-clips-at-one-place",
        "a-grid-not-filled"])
def test_what_the_spec_does_not_define_is_refused(tmp_path, edit, message):
    archive = golden_with(edit, tmp_path / "edited.mcz")
    if message is None:  # the golden file, rewritten: every stream claimed, every rule met
        with Archive(archive) as opened:
            opened.verify()
        return
    with pytest.raises(ArchiveError) as refused:
        with Archive(archive):
            pass
    assert str(refused.value).startswith(f"{archive}: {message}")


def test_an_unclaimed_patch_stream_fails_mcz_test_in_one_line(tmp_path):
    archive = golden_with(lambda meta, streams: streams.update({"patch/00002": streams["patch/00001"]}),
                          tmp_path / "extra.mcz")
    result = CliRunner().invoke(main, ["test", "-q", str(archive)])
    assert result.exit_code == 1
    assert result.output == f"mcz: error: {archive}: patch/00002: a stream that no part of meta claims\n"


def test_the_encoder_never_tries_ranks_whose_model_a_reader_refuses():
    """A class of 100,000 frames: U_frames of 330 columns is within the matrix limits (33,000,000
    values), but more numbers than a model may store; of 80 (8,000,000), not."""
    assert not tensor._storable((100_000, 60, 2), (330, 8, 2))
    assert tensor._storable((100_000, 60, 2), (80, 8, 2))


# --------------------------------------------------------------------------- the generated suite


@pytest.fixture(scope="session")
def stream_bases(shared_data, tmp_path_factory) -> dict[str, Path]:
    """Each of hostile_streams.BASES compressed once per session (about a second each); the tensor
    class forced to its model (`tensor._pays`), which pays on none of the shared data."""
    root = tmp_path_factory.mktemp("stream_bases")
    made = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(tensor, "_pays", lambda tensor_bytes, best_bytes: True)
        for name, (folders, options) in hostile_streams.BASES.items():
            for folder, files in folders.items():
                linked(root / name / folder, *(shared_data / file for file in files))
            made[name] = root / f"{name}.mcz"
            result = CliRunner().invoke(main, ["compress", str(root / name), "-o", str(made[name]), "-q", "-j", "1",
                                               *options])
            assert result.exit_code == 0, result.output
    return made


def test_the_bases_hold_what_the_cases_change_and_decode_as_the_spec_says(stream_bases, tmp_path):
    with Archive(stream_bases["plant"]) as plant:
        assert [row["path"] for row in plant.clips] == ["07/07_10.amc", "09/09_03.amc"]
        assert plant.clips[0]["frames"] == 301 and plant.clips[0]["planted_stances"] >= 2  # stances for the cases to replace
        assert all("patched_frames" in row and "planted_stances" in row for row in plant.clips)
    with Archive(stream_bases["tensor"]) as model:
        (row,) = model.meta["classes"]
        assert row["model"] == "tensor" and row["modes"] == ["actor", "motion"] and model.settings.transform == {
            "id": "dwt", "wavelet": "db4", "level": None}
        frames = [clip["frames"] for clip in model.clips]
        assert frames.index(max(frames)) == hostile_streams.LONGEST
        assert {name.split("/")[0] for name in model.stream_sizes()} >= {"tensor", "warp"}
    for name, base in stream_bases.items():
        check_against_package(base, tmp_path / name)


AGREEMENT = 1e-5  # AMC units: a foot lock over a whole clip carries the two decoders' roundings to 1.3e-7


def decodes_as_the_reference_decoder_does(archive: Path) -> None:
    """Every clip of `archive` as mcz decodes it and as the reference decoder (docs/format.md alone) does."""
    reference = reference_decoder.decode_archive(archive)
    with Archive(archive) as opened:
        for index, row in enumerate(opened.clips):
            np.testing.assert_allclose(opened.decode(index).values, reference[row["path"]], rtol=0, atol=AGREEMENT,
                                       err_msg=row["path"])


@pytest.mark.slow
@pytest.mark.parametrize("name", [case.name for case in CASES])
def test_hostile_stream_is_refused_in_one_line_or_decoded_as_specified(stream_bases, name, tmp_path):
    case = next(c for c in CASES if c.name == name)
    archive = tmp_path / "hostile.mcz"
    hostile_archives.build(case, archive, stream_bases[case.base])
    before = hostile_archives.files_under(tmp_path)
    result = hostile_archives.run_mcz("test", "-q", str(archive))
    assert hostile_archives.files_under(tmp_path) == before
    if case.may_decode and result.returncode == 0 and not result.stderr:
        decodes_as_the_reference_decoder_does(archive)
        return
    lines = result.stderr.splitlines()
    assert result.returncode == 1 and not result.stdout and len(lines) == 1, result.stderr[-3000:]
    assert lines[0].startswith(f"mcz: error: {archive}: ") and case.section in lines[0], lines[0]

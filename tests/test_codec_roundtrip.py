"""End-to-end round trips through `mcz compress` / `mcz decompress` on real clips.

The error is measured independently of the codec: the decompressed AMC text is read
back by the formats module and run through forward kinematics against the original.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.archive import Archive, Settings, compress
from mocapzip.cli.main import main
from mocapzip.codec.lossless import decode_channels, encode_channels
from mocapzip.formats.amc import read_amc
from mocapzip.api import bvh_joint_positions
from mocapzip.formats.bvh import parse_bvh, read_bvh
from mocapzip.formats.asf import read_asf
from mocapzip.formats.mcz import FORMAT_VERSION
from mocapzip.inputs.glitches import find_glitches, glitch_mask
from mocapzip.motion.contacts import contacts
from mocapzip.motion.kinematics import forward
from mocapzip.codec.clip_stream import CodedClip
from mocapzip.ratecontrol.encode import ROOT_STEP_RATIO
from mocapzip.motion.metrics import skin_error
from mocapzip.motion.rotations import rotation_angle
from mocapzip.motion.skeleton import SkeletonModel

GOLDEN = Path(__file__).parent / "golden"


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def clip_errors(original_dir: Path, decoded_dir: Path, relpaths) -> dict[str, float]:
    """Mean joint-position error (cm) of each decoded AMC against its original."""
    errors = {}
    for rel in relpaths:
        asf = next((original_dir / rel).parent.glob("*.asf"))
        skeleton = read_asf(asf)
        model = SkeletonModel.from_asf(skeleton)
        original = read_amc(original_dir / rel, skeleton)
        decoded = read_amc(decoded_dir / rel, read_asf(decoded_dir / Path(rel).parent / asf.name))
        assert decoded.bones == original.bones and decoded.header == original.header
        assert np.array_equal(decoded.frame_numbers, original.frame_numbers)
        a = forward(model, original.values, original).positions
        b = forward(model, decoded.values, decoded).positions
        errors[rel] = float(np.linalg.norm(a - b, axis=-1).mean())
    return errors


@pytest.fixture(scope="module")
def small_set(tmp_path_factory, shared_data) -> Path:
    """Two subjects, walk and run, kept short so the suite stays fast: a folder of real files."""
    root = tmp_path_factory.mktemp("input")
    for subject, names in (("09", ["09_01.amc", "09_05.amc"]), ("07", ["07_01.amc"])):
        (root / subject).mkdir()
        shutil.copy(shared_data / "cmu" / subject / f"{subject}.asf", root / subject)
        for name in names:
            shutil.copy(shared_data / "cmu" / subject / name, root / subject / name)
    return root


@pytest.mark.parametrize("error_cm", [1.0, 0.5])
def test_lossy_round_trip_meets_the_target(small_set, tmp_path, error_cm):
    archive = tmp_path / "db.mcz"
    result = run("compress", small_set, "-o", archive, "-e", error_cm, "-q", "-j", "1")
    assert result.exit_code == 0, result.output
    assert run("decompress", archive, "-o", tmp_path / "out", "-q").exit_code == 0
    rels = ["07/07_01.amc", "09/09_01.amc", "09/09_05.amc"]
    measured = clip_errors(small_set, tmp_path / "out", rels)
    assert all(0 < e <= error_cm for e in measured.values()), measured
    stored = {c["path"]: c["error_cm"] for c in json.loads(run("info", archive, "--json").output)["clips"]}
    for rel in rels:  # the stored error is the real one (up to the 6-digit text rounding)
        assert abs(stored[rel] - measured[rel]) < 1e-3
    # The skeleton comes back byte for byte.
    assert (tmp_path / "out/07/07.asf").read_bytes() == (small_set / "07/07.asf").read_bytes()


def test_lower_error_costs_more_bytes(small_set, tmp_path):
    sizes = [compress([small_set], tmp_path / f"{e}.mcz", Settings(error_cm=e))["output_bytes"] for e in (2.0, 0.5)]
    assert sizes[0] < sizes[1]


@pytest.mark.parametrize("representation", ["channels", "positions", "scaled", "normalised"])
def test_every_representation_round_trips_within_target(small_set, tmp_path, representation):
    settings = Settings(error_cm=1.0, representation=representation, classes="single")
    compress([small_set / "09"], tmp_path / "db.mcz", settings)
    with Archive(tmp_path / "db.mcz") as archive:
        for i, row in enumerate(archive.clips):
            assert row["error_cm"] <= 1.0
            assert archive.decode(i).values.shape == (row["frames"], 62)


def test_root_track_step_is_a_fixed_share_of_the_pose_step(small_set, tmp_path):
    """A root error moves every joint, so the root track is coded finer (ratecontrol.encode.ROOT_STEP_RATIO)."""
    compress([small_set], tmp_path / "db.mcz", Settings(error_cm=1.0))
    with Archive(tmp_path / "db.mcz") as archive:
        for i in range(len(archive.clips)):
            coded = CodedClip.from_payload(archive._reader.read(f"clip/{i:05d}"),
                                           archive.settings.coefficient_coder, priors=archive.priors)
            assert coded.root_step == pytest.approx(ROOT_STEP_RATIO * coded.pose_step, rel=1e-6)
            assert np.any(coded.root_ints)


def test_solved_bones_decode_with_the_twists_the_encoder_chose(shared_data, tmp_path):
    """Format 4 leaves out the axes of bones the joint positions fix (CMU: 180 -> 129 values),
    except for which of two twists a 2-dof bone takes: the row's twist_flips say, and the
    decoder must follow them (subject 64's left thumb sits in the non-default one)."""
    inputs = [shared_data / "cmu" / "64" / name for name in ("64_01.amc", "64_02.amc")]
    compress(inputs, tmp_path / "db.mcz", Settings(error_cm=1.0))
    model = SkeletonModel.from_asf(read_asf(shared_data / "cmu/64/64.asf"))
    with Archive(tmp_path / "db.mcz") as archive:
        assert archive.settings.axes_from_positions and archive.basis(0).components.shape[0] == 129
        for i, row in enumerate(archive.clips):
            assert set(row["twist_flips"]) == {"lthumb"}
            original = read_amc(shared_data / "cmu" / "64" / row["path"])
            truth = forward(model, original.values, original)
            with_flips = forward(model, archive.decode(i).values, original)
            del row["twist_flips"]
            without = forward(model, archive.decode(i).values, original)
            assert np.linalg.norm(with_flips.positions - truth.positions, axis=-1).mean() <= 1.0 + 1e-6
            thumb = model.index["lthumb"]  # lossy, but not half a turn off
            errors = [np.median(rotation_angle(pose.rotations[:, thumb], truth.rotations[:, thumb]))
                      for pose in (with_flips, without)]
            assert errors[0] < 1.0 < 2.0 < errors[1]
            assert skin_error(model, truth, with_flips) < skin_error(model, truth, without)


def test_dwt_and_forced_split(small_set, tmp_path):
    settings = Settings(error_cm=1.0, transform={"id": "dwt", "wavelet": "db4", "level": None}, split=[0.2, 0.4, 0.4])
    summary = compress([small_set / "09"], tmp_path / "db.mcz", settings)
    assert summary["worst_error_cm"] <= 1.0


def test_poly_transform_round_trips_within_target(small_set, tmp_path):
    """-t poly (piecewise polynomials of the PCA curves, seed 003): every clip within -e,
    measured on the decompressed files; the archive names the knot spacing it was coded with."""
    archive = tmp_path / "db.mcz"
    result = run("compress", small_set, "-o", archive, "-e", 1, "-t", "poly", "--knot-spacing", 90, "-q", "-j", "1")
    assert result.exit_code == 0, result.output
    assert run("decompress", archive, "-o", tmp_path / "out", "-q").exit_code == 0
    measured = clip_errors(small_set, tmp_path / "out", ["07/07_01.amc", "09/09_01.amc", "09/09_05.amc"])
    assert all(0 < e <= 1.0 for e in measured.values()), measured
    info = json.loads(run("info", archive, "--json").output)
    assert info["settings"]["transform"] == {"id": "poly", "knot_spacing": 90}


def test_knot_spacing_is_refused_without_poly(small_set, tmp_path):
    result = run("compress", small_set, "-o", tmp_path / "db.mcz", "--knot-spacing", 60)
    assert result.exit_code == 2 and "--knot-spacing is for --transform poly" in result.output
    assert not (tmp_path / "db.mcz").exists()


def test_lossless_cli_is_exact_on_odd_exporters(shared_data, tmp_path):
    """Vicon Blade writes fixed 6 decimals; cmu-edited files have no headers or final newline."""
    out = tmp_path / "out"
    inputs = [shared_data / "other-vicon-blade" / "walk_200fps", shared_data / "cmu-edited" / "07"]
    for i, folder in enumerate(inputs):
        asf = ["--asf", shared_data / "cmu/07/07.asf"] if "edited" in str(folder) else []
        assert run("compress", folder, "-o", tmp_path / f"{i}.mcz", "--lossless", "-q", *asf).exit_code == 0
        assert run("decompress", tmp_path / f"{i}.mcz", "-o", out / str(i), "-q").exit_code == 0
        for amc in folder.glob("*.amc"):
            a, b = read_amc(amc), read_amc(out / str(i) / amc.name)
            assert a.header == b.header and a.bones == b.bones
            assert np.array_equal(a.values, b.values), amc


@pytest.mark.slow
def test_lossless_channel_coding_is_exact_on_every_shared_amc(shared_data):
    files = sorted(p for p in shared_data.rglob("*") if p.suffix.lower() == ".amc")
    assert len(files) > 150
    for path in files:
        values = read_amc(path).values
        assert np.array_equal(decode_channels(encode_channels(values)), values), path


@pytest.mark.parametrize("version", range(1, FORMAT_VERSION + 1))
def test_golden_archives_keep_decoding(shared_data, version):
    def source(row):  # golden inputs are CMU files named SUBJECT_TRIAL.amc
        folder = shared_data / "cmu" / row["path"].split("_")[0]
        return folder / row["path"], folder / f"{folder.name}.asf"

    bandai = shared_data / "bvh-bandai"  # from version 8 one BVH clip joins them
    with Archive(GOLDEN / f"lossless_v{version}.mcz") as archive:
        assert archive.format_version == version
        assert sum("bvh" in row for row in archive.clips) == (version >= 8)
        for i, row in enumerate(archive.clips):
            if "bvh" in row:
                assert archive.file_bytes("motion", i) == (bandai / row["path"]).read_bytes()
                continue
            assert np.array_equal(archive.decode(i).values, read_amc(source(row)[0]).values)
    with Archive(GOLDEN / f"lossy_v{version}.mcz") as archive:
        assert archive.format_version == version
        assert archive.settings.coefficient_coder == {1: "zstd", 2: "context"}.get(version, "primed")
        assert archive.settings.axes_from_positions == (version >= 4)
        flipped = 0
        for i, row in enumerate(archive.clips):
            if "bvh" in row:  # its joints and End Sites, against the source's
                assert "extra_root" in row["bvh"]  # the extra root moves: its channels have a stream
                original = bvh_joint_positions(read_bvh(bandai / row["path"]))
                decoded = bvh_joint_positions(parse_bvh(archive.file_bytes("motion", i)))
                distances = np.linalg.norm(original - decoded, axis=-1)
                assert distances.mean() <= row["error_cm"] + 1e-3 <= 1.0 + 1e-3
                assert distances.max() <= 3.0 + 1e-3
                assert row.get("patched_frames", 0) > 0 or version >= 10  # (tests/make_golden_archives.py)
                continue
            amc, asf = source(row)
            assert archive.skeleton_text(row["skeleton"]).encode("latin-1") == asf.read_bytes()
            model = SkeletonModel.from_asf(read_asf(asf))
            original, decoded = read_amc(amc), archive.decode(i)
            a, b = forward(model, original.values, original), forward(model, decoded.values, decoded)
            distances = np.linalg.norm(a.positions - b.positions, axis=-1)
            assert distances.mean() <= row["error_cm"] + 1e-3 <= 1.0 + 1e-3
            if version >= 5:  # the golden file bounds every joint at 3 cm (--max-error), with frame patches
                assert archive.settings.max_error_cm == 3.0 and row["patched_frames"] > 0
                # from version 6 glitches are repaired (64_01's left thumb): those joints may pass the bound
                freed = glitch_mask(model, find_glitches(read_asf(asf), model, original, a.positions, 120.0),
                                    original.frame_numbers) if version >= 6 else np.zeros(distances.shape, bool)
                assert distances[~freed].max() <= 3.0 + 1e-3
                assert ("repaired" in row) == freed.any()
            if version >= 6:  # ... and planted feet at 2 cm (--contact-error)
                planted = contacts(model, a.positions, archive.settings.fps) & ~freed
                assert archive.settings.contact_error_cm == 2.0 and planted.any()
                assert distances[planted].max() <= 2.0 + 1e-3
            for name in row.get("twist_flips", {}):  # the flipped bones come out the right way round
                j = model.index[name]
                assert np.median(rotation_angle(a.rotations[:, j], b.rotations[:, j])) < 1.0
                flipped += 1
        assert flipped == (1 if version >= 4 else 0)


def test_cli_refuses_to_overwrite_and_extracts_by_pattern(small_set, tmp_path):
    archive = tmp_path / "db.mcz"
    assert run("compress", small_set, "-o", archive, "-q", "-e", "2").exit_code == 0
    again = run("compress", small_set, "-o", archive, "-q")
    assert again.exit_code == 1 and "already exists" in again.output
    assert run("compress", small_set, "-o", archive, "-q", "-f", "-e", "2").exit_code == 0
    result = run("decompress", archive, "-o", tmp_path / "out", "--clip", "09/*", "-q")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "out").rglob("*")) == ["09", "09.asf", "09_01.amc", "09_05.amc"]
    assert run("decompress", archive, "-o", tmp_path / "out", "--clip", "09/*", "-q").exit_code == 1
    assert run("test", archive, "-q").exit_code == 0


def test_damaged_archive_is_refused_with_the_clip_named(small_set, tmp_path):
    archive = tmp_path / "db.mcz"
    compress([small_set], archive, Settings(error_cm=2.0))
    data = bytearray(archive.read_bytes())
    data[-40] ^= 0xFF  # inside the payload: the last clip's stream
    archive.write_bytes(bytes(data))
    for command in (("test", archive), ("decompress", archive, "-o", tmp_path / "out")):
        result = run(*command)
        assert result.exit_code == 1
        assert "clip/" in result.output and "Traceback" not in result.output


def test_missing_skeleton_is_exit_1(shared_data, tmp_path):
    result = run("compress", shared_data / "cmu-edited" / "91", "-o", tmp_path / "x.mcz")
    assert result.exit_code == 1 and "no skeleton" in result.output
    assert not (tmp_path / "x.mcz").exists()

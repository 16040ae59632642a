"""`--classes pooled`, the default: subjects with few frames share one basis, the others keep their own."""

from __future__ import annotations

import os

import numpy as np
import pytest
from click.testing import CliRunner

from mocapzip.archive import Archive
from mocapzip.classes.by_name import POOL_FRAMES, pooled_classes
from mocapzip.cli.main import main
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel


def test_small_subjects_of_one_width_share_a_pool():
    frames = {"a": POOL_FRAMES, "b": POOL_FRAMES - 1, "c": 10, "d": 20}
    assert pooled_classes(frames, dict.fromkeys(frames, 129)) == {"a": "a", "b": "pooled", "c": "pooled", "d": "pooled"}


def test_a_pool_never_takes_a_subjects_name():
    frames = {"pooled": 99_999, "a": 10, "b": 20}
    assert pooled_classes(frames, dict.fromkeys(frames, 129)) == {"pooled": "pooled", "a": "pooled+", "b": "pooled+"}


def test_pools_split_by_pose_width_and_a_pool_of_one_keeps_its_name():
    frames = {"a": 10, "b": 20, "c": 30}
    widths = {"a": 129, "b": 129, "c": 90}
    assert pooled_classes(frames, widths) == {"a": "pooled-129", "b": "pooled-129", "c": "c"}


def test_compress_pools_the_short_subjects_of_a_real_set(shared_data, tmp_path):
    """09, 93 and 07 with one short clip each share a basis; 13 (three clips, 11,897 frames) keeps its own.
    Every clip still meets the default target, end to end."""
    cmu = shared_data / "cmu"
    picks = {"09": ["09_01.amc"], "93": ["93_04.amc"], "07": ["07_01.amc"], "13": ["13_17.amc", "13_29.amc", "13_30.amc"]}
    for subject, names in picks.items():
        (tmp_path / "in" / subject).mkdir(parents=True)
        for name in [f"{subject}.asf", *names]:
            os.symlink(cmu / subject / name, tmp_path / "in" / subject / name)
    archive, out = tmp_path / "db.mcz", tmp_path / "out"
    result = CliRunner().invoke(main, ["compress", str(tmp_path / "in"), "-o", str(archive), "-q"])
    assert result.exit_code == 0, result.output
    with Archive(archive) as opened:
        assert opened.meta["settings"]["classes"] == "pooled"
        classes = {c["name"]: c["clips"] for c in opened.meta["classes"]}
        rows = {row["path"]: row for row in opened.clips}
    assert classes == {"13": 3, "pooled": 3}
    assert CliRunner().invoke(main, ["decompress", str(archive), "-o", str(out), "-q"]).exit_code == 0
    for subject, names in picks.items():
        model = SkeletonModel.from_asf(read_asf(cmu / subject / f"{subject}.asf"))
        for name in names:
            a, b = read_amc(cmu / subject / name), read_amc(out / subject / name)
            distances = np.linalg.norm(forward(model, a.values, a).positions - forward(model, b.values, b).positions,
                                       axis=-1)
            assert distances.mean() <= 1.0 + 1e-6 and distances.max() <= 10.0 + 1e-6, name
            assert distances.mean() == pytest.approx(rows[f"{subject}/{name}"]["error_cm"], abs=1e-6)

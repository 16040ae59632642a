"""Automatic classes (`--classes auto[:K]`): k-subspaces with PPCA, deterministic annealing,
the byte estimate, and compress/decompress round trips on short real clips."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mocapzip.autoclass import (ByteProxy, ClipStats, _weighted_truncation, anneal, auto_classes, kss_ppca,
                                parse_auto, plan)
from mocapzip.codec.pca import PcaBasis
from mocapzip.formats.errors import MocapFormatError


def subspace_clips(rng, groups=3, per_group=4, dim=12, rank=2, frames=60):
    """Clips drawn from `groups` different low-dimensional subspaces (with different means)."""
    stats, truth = [], []
    for g in range(groups):
        directions = np.linalg.qr(rng.normal(size=(dim, rank)))[0]
        centre = rng.normal(size=dim) * 3
        for _ in range(per_group):
            poses = centre + rng.normal(size=(frames, rank)) * [4.0, 2.0][:rank] @ directions.T
            stats.append(ClipStats.of(poses + 0.01 * rng.normal(size=poses.shape)))
            truth.append(g)
    return stats, np.array(truth)


def same_partition(a, b) -> bool:
    pairs = {(int(x), int(y)) for x, y in zip(a, b)}
    return len(pairs) == len(set(a)) == len(set(b))


def test_parse_auto():
    assert parse_auto("auto") is None
    assert parse_auto("auto:3") == 3
    assert parse_auto("subject") is False and parse_auto("classes.csv") is False
    for bad in ("auto:0", "auto:x", "auto:"):
        with pytest.raises(MocapFormatError):
            parse_auto(bad)


@pytest.mark.parametrize("seed", [0, 1])
def test_kss_and_annealing_recover_subspaces(seed):
    stats, truth = subspace_clips(np.random.default_rng(seed))
    assert same_partition(kss_ppca(stats, 3, seed=seed), truth)
    assert same_partition(anneal(stats, 3, dims=2, seed=seed), truth)
    np.testing.assert_array_equal(kss_ppca(stats, 3, seed=seed), kss_ppca(stats, 3, seed=seed))  # deterministic


def test_weighted_truncation_from_stats_matches_frames():
    rng = np.random.default_rng(5)
    poses = rng.normal(size=(50, 6)) @ rng.normal(size=(6, 6)) + 10
    others = rng.normal(size=(80, 6)) * 2
    pca = PcaBasis.fit(ClipStats_accumulator(others))
    weights = rng.uniform(0.5, 3.0, size=6)
    gram = pca.components.T @ (weights[:, None] * pca.components)
    curve = _weighted_truncation(ClipStats.of(poses), pca.mean, pca.components, gram)
    for q in range(7):
        approx = pca.mean + (poses - pca.mean) @ pca.components[:, :q] @ pca.components[:, :q].T
        direct = ((poses - approx) ** 2 * weights).sum(axis=1).mean()
        assert curve[q] == pytest.approx(direct, rel=1e-9, abs=1e-9)


def ClipStats_accumulator(rows):
    from mocapzip.codec.pca import CovarianceAccumulator

    acc = CovarianceAccumulator(rows.shape[1])
    acc.add(rows)
    return acc


@pytest.fixture(scope="module")
def short_clips(shared_data):
    """Three short walks (subject 07) and three runs (09), in the codec's representation."""
    from mocapzip.archive import Settings
    from mocapzip.clip import load_clips
    from mocapzip.inputs import find_clips

    cmu = shared_data / "cmu"
    paths = [cmu / "07" / f"07_{i:02d}.amc" for i in (1, 9, 10)] + [cmu / "09" / f"09_{i:02d}.amc" for i in (1, 2, 3)]
    settings = Settings()
    sources = find_clips(paths)
    skeletons = sorted({s.asf for s in sources})
    try:
        clips = load_clips(sources, skeletons, settings.representation, settings.axis_weight_cm)
    except AttributeError:  # a codec without pose weights
        clips = load_clips(sources, skeletons, settings.representation)
    return clips, settings, ByteProxy.calibrate(clips, settings, jobs=2), paths


def test_auto_classes_on_real_walks_and_runs(short_clips):
    clips, settings, proxy, _ = short_clips
    walk = np.array([c.source.relpath.startswith("07") for c in clips])
    forced = plan(clips, 2, settings, proxy=proxy, restarts=2)
    assert forced.k == 2 and same_partition(forced.labels, walk)
    chosen = plan(clips, None, settings, proxy=proxy, max_k=3, restarts=1)
    assert 1 <= chosen.k <= 3
    assert chosen.estimated_bytes == min(c["bytes"] for c in chosen.candidates)
    assert chosen.estimated_bytes <= proxy.partition_bytes(np.zeros(len(clips), int))
    # the byte estimate tracks the codec: one class needs more components than walk or run alone
    proxy.partition_bytes(walk.astype(int))
    details = {len(k): v for k, v in proxy.details.items()}
    assert details[6]["components"] > max(v["components"] for k, v in proxy.details.items() if len(k) == 3)


def test_round_trip_with_auto_classes(short_clips, tmp_path):
    """compress --classes auto:2 (or, before archive.compress knows `auto`, the same classes
    through a class table), decompress, and check every clip's error from the written AMC."""
    from mocapzip import archive
    from mocapzip.formats.amc import read_amc
    from mocapzip.formats.asf import read_asf
    from mocapzip.kinematics import forward
    from mocapzip.metrics import mean_joint_error
    from mocapzip.skeleton import SkeletonModel

    clips, settings, _, paths = short_clips
    chosen = [paths[0], paths[1], paths[3], paths[4]]
    out = tmp_path / "auto.mcz"
    settings = archive.Settings(classes="auto:2")
    try:
        summary = archive.compress(chosen, out, settings, jobs=2)
        native = True
    except MocapFormatError as exc:
        assert "unknown --classes" in str(exc)
        names = auto_classes([c for c in clips if c.source.amc in chosen], 2, settings, jobs=2)
        table = tmp_path / "classes.csv"
        table.write_text("".join(f"{p},{n}\n" for p, n in names.items()))
        settings.classes = str(table)
        summary = archive.compress(chosen, out, settings, jobs=2)
        native = False
    assert summary["worst_error_cm"] <= 1.0
    info = archive.info(out)
    assert sorted(c["name"] for c in info["classes"]) == ["auto0", "auto1"]
    by_class = {c["name"]: {r["path"][:2] for r in info["clips"] if r["class"] == i} for i, c in enumerate(info["classes"])}
    assert sorted(map(sorted, by_class.values())) == [["07"], ["09"]]
    if native:
        assert info["auto_classes"][0]["k"] == 2
    archive.decompress(out, tmp_path / "out")
    for path in chosen:
        skeleton = read_asf(path.parent / f"{path.parent.name}.asf")
        model = SkeletonModel.from_asf(skeleton)
        original = read_amc(path, skeleton)
        decoded = read_amc(tmp_path / "out" / path.name, skeleton)
        error = mean_joint_error(forward(model, original.values, original).positions,
                                 forward(model, decoded.values, decoded).positions)
        assert error <= 1.0 + 1e-6, (path.name, error)
    json.dumps(info)  # meta stays JSON


def test_ppca_segmentation_cuts_where_the_behaviour_changes(shared_data):
    """segment.py (Barbic et al. via Hou et al. VI-B2): synthetic blocks, then run -> walk of subject 35."""
    from mocapzip.clip import load_clips
    from mocapzip.inputs import find_clips
    from mocapzip.segment import segment_take

    rng = np.random.default_rng(7)
    a = rng.normal(size=(400, 2)) @ rng.normal(size=(2, 10)) + 0.01 * rng.normal(size=(400, 10))
    b = rng.normal(size=(300, 2)) @ rng.normal(size=(2, 10)) + 3 + 0.01 * rng.normal(size=(300, 10))
    cuts = segment_take(np.vstack([a, b]), min_frames=120, horizon=60)
    assert len(cuts) == 3 and abs(cuts[1] - 400) <= 20
    assert segment_take(a, min_frames=120, horizon=60) == [0, 400]

    cmu = shared_data / "cmu" / "35"
    sources = find_clips([cmu / "35_17.amc", cmu / "35_18.amc", cmu / "35_01.amc"])
    clips = {c.source.relpath: c.poses for c in load_clips(sources, [sources[0].asf], "normalised")}
    runs = np.vstack([clips["35_17.amc"], clips["35_18.amc"]])
    cuts = segment_take(np.vstack([runs, clips["35_01.amc"]]), min_frames=120, horizon=60)
    assert len(cuts) == 3 and abs(cuts[1] - len(runs)) <= 40, cuts
    assert segment_take(clips["35_01.amc"]) == [0, len(clips["35_01.amc"])]  # one walk: no cut

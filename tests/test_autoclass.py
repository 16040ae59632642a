"""Automatic classes (`--classes auto[:K]`) and segments (`--segment`): k-subspaces with PPCA,
deterministic annealing, the byte estimate, PPCA segmentation, and compress/decompress round
trips on short real clips (API and CLI)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mocapzip.classes.auto import _Moments, anneal, kss_ppca, parse_auto, plan
from mocapzip.codec.pca import PcaBasis
from mocapzip.formats.errors import MocapFormatError
from mocapzip.classes.ppca import PpcaModel
from mocapzip.ratecontrol.class_bytes import ByteProxy, ClipStats, _weighted_truncation, union_pca


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


def residual_per_frame(stat, mean: np.ndarray, basis: np.ndarray) -> float:
    """The per-clip formula: mean squared residual per frame on the affine subspace (mean, basis)."""
    delta = stat.mean - mean
    second = stat.scatter / stat.count + np.outer(delta, delta)
    return max(float(np.trace(second) - ((second @ basis) * basis).sum()), 0.0)


def test_stacked_moments_match_per_clip_statistics():
    """The vectorised scores, merges and residuals (`_Moments`) agree with the per-clip formulas."""
    stats, _ = subspace_clips(np.random.default_rng(3))
    moments = _Moments.of(stats)
    weights = np.random.default_rng(4).uniform(0, 1, len(stats))
    model = PpcaModel.from_pca(union_pca(stats[:4]))
    expected = [model.mean_log_density_from_stats(s.count, s.mean, s.scatter) for s in stats]
    np.testing.assert_allclose(moments.mean_log_densities(model), expected, rtol=1e-9)
    pca, direct = moments.pca(weights), union_pca(stats, weights)
    np.testing.assert_allclose(pca.mean, direct.mean, rtol=1e-9)
    np.testing.assert_allclose(pca.variances, direct.variances, rtol=1e-7, atol=1e-9)
    basis = direct.components[:, :2]
    np.testing.assert_allclose(moments.residuals(direct.mean, basis),
                               [residual_per_frame(s, direct.mean, basis) for s in stats], rtol=1e-7, atol=1e-9)


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
    from mocapzip.archive.settings import checked
    from mocapzip.inputs.clip import load_clips
    from mocapzip.inputs.discover import find_clips

    cmu = shared_data / "cmu"
    paths = [cmu / "07" / f"07_{i:02d}.amc" for i in (1, 9, 10)] + [cmu / "09" / f"09_{i:02d}.amc" for i in (1, 2, 3)]
    settings = checked(Settings())  # its representation as compress resolves it
    sources = find_clips(paths)
    try:
        clips = load_clips(sources, settings.representation, settings.axis_weight_cm)
    except AttributeError:  # a codec without pose weights
        clips = load_clips(sources, settings.representation)
    target = settings.coding_target()
    return clips, target, ByteProxy.calibrate(clips, target, jobs=2), paths


def test_auto_classes_on_real_walks_and_runs(short_clips):
    clips, target, proxy, _ = short_clips
    walk = np.array([c.source.relpath.startswith("07") for c in clips])
    forced = plan(clips, 2, target, proxy=proxy, restarts=2)
    assert forced.k == 2 and same_partition(forced.labels, walk)
    chosen = plan(clips, None, target, proxy=proxy, max_k=3, restarts=1)
    assert 1 <= chosen.k <= 3
    assert chosen.estimated_bytes == min(c["bytes"] for c in chosen.candidates)
    assert chosen.estimated_bytes <= proxy.partition_bytes(np.zeros(len(clips), int))
    best_kss = min((c for c in chosen.candidates if c["method"] != "anneal"), key=lambda c: c["bytes"])
    assert {c["k"] for c in chosen.candidates if c["method"] == "anneal"} <= {best_kss["k"]}  # annealing: best K only
    # the byte estimate tracks the codec: one class needs more components than walk or run alone
    proxy.partition_bytes(walk.astype(int))
    details = {len(k): v for k, v in proxy.details.items()}
    assert details[6]["components"] > max(v["components"] for k, v in proxy.details.items() if len(k) == 3)


def decoded_errors(original_path, decoded_path):
    """Per-frame mean joint error (cm) of a decompressed AMC against its original, read back from disk
    (independent of the codec), and the two files' frame numbers."""
    from mocapzip.formats.amc import read_amc
    from mocapzip.formats.asf import read_asf
    from mocapzip.motion.kinematics import forward
    from mocapzip.motion.metrics import frame_errors
    from mocapzip.motion.skeleton import SkeletonModel

    skeleton = read_asf(original_path.parent / f"{original_path.parent.name}.asf")
    model = SkeletonModel.from_asf(skeleton)
    original, decoded = read_amc(original_path, skeleton), read_amc(decoded_path, skeleton)
    assert decoded.header == original.header and decoded.bones == original.bones
    errors = frame_errors(forward(model, original.values, original).positions,
                          forward(model, decoded.values, decoded).positions)
    return errors, original.frame_numbers, decoded.frame_numbers


def test_round_trip_with_auto_classes(short_clips, tmp_path):
    """compress --classes auto:2 natively, decompress, and check every clip's error from the written AMC."""
    from mocapzip import archive

    _, _, _, paths = short_clips
    chosen = [paths[0], paths[1], paths[3], paths[4]]
    out = tmp_path / "auto.mcz"
    summary = archive.compress(chosen, out, archive.Settings(classes="auto:2"), jobs=1)
    assert summary["worst_error_cm"] <= 1.0
    info = archive.info(out)
    assert sorted(c["name"] for c in info["classes"]) == ["auto0", "auto1"]
    by_class = {c["name"]: {r["path"][:2] for r in info["clips"] if r["class"] == i} for i, c in enumerate(info["classes"])}
    assert sorted(map(sorted, by_class.values())) == [["07"], ["09"]]
    assert info["auto_classes"][0]["k"] == 2 and info["auto_classes"][0]["clips"] == 4
    archive.decompress(out, tmp_path / "out")
    for path in chosen:
        errors, _, _ = decoded_errors(path, tmp_path / "out" / path.name)
        assert errors.mean() <= 1.0 + 1e-6, (path.name, errors.mean())
    json.dumps(info)  # meta stays JSON


@pytest.mark.slow
def test_segmented_take_decodes_whole_within_target(shared_data, tmp_path):
    """--segment on a real boxing take that PPCA cuts in four: one AMC back with the original's
    frames, the whole take within the target, no jump at the cuts, and (auto:2) several classes."""
    from mocapzip import archive

    take = shared_data / "cmu" / "02" / "02_05.amc"
    out = tmp_path / "seg.mcz"
    archive.compress([take], out, archive.Settings(classes="auto:2", segment=True), jobs=1)
    with archive.Archive(out) as opened:
        opened.verify()
        row = opened.clips[0]
    segments = row["segments"]
    assert len(segments) >= 2 and segments[0]["first"] == 0
    assert all(a["first"] + a["frames"] == b["first"] for a, b in zip(segments, segments[1:]))
    assert segments[-1]["first"] + segments[-1]["frames"] == row["frames"]
    assert len({s["class"] for s in segments}) == 2  # one take, two class bases
    archive.decompress(out, tmp_path / "out")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["02.asf", "02_05.amc"]
    errors, original_frames, decoded_frames = decoded_errors(take, tmp_path / "out" / "02_05.amc")
    assert np.array_equal(decoded_frames, original_frames)
    assert errors.mean() <= 1.0 and abs(errors.mean() - row["error_cm"]) < 1e-3  # the stored error is the real one
    for cut in (s["first"] for s in segments[1:]):
        assert errors[cut - 5 : cut + 5].mean() <= 2.0, (cut, errors[cut - 5 : cut + 5])


@pytest.mark.slow
def test_cli_auto_classes_and_segments(shared_data, tmp_path):
    """`mcz compress -c auto --segment` (K chosen by size) and `mcz info` listing what was chosen."""
    from click.testing import CliRunner

    from mocapzip.cli.main import main

    def run(*args):
        return CliRunner().invoke(main, [str(a) for a in args])

    cmu = shared_data / "cmu"
    takes = [cmu / "07" / "07_01.amc", cmu / "09" / "09_01.amc", cmu / "02" / "02_05.amc"]
    out = tmp_path / "db.mcz"
    result = run("compress", *takes, "-o", out, "-c", "auto", "--segment", "-q", "-j", "1")
    assert result.exit_code == 0, result.output
    report = json.loads(run("info", out, "--json").output)
    chosen = report["auto_classes"][0]
    assert chosen["k"] == len(report["classes"]) >= 1
    assert chosen["estimated_bytes"] == min(c["bytes"] for c in chosen["candidates"])
    segmented = [c for c in report["clips"] if "segments" in c]
    assert [c["path"] for c in segmented] == ["02_05.amc"]
    assert chosen["clips"] == 2 + len(segmented[0]["segments"])  # the planner saw segments, not the take
    text = run("info", out).output
    assert f"auto classes: K={chosen['k']}" in text and "02_05.amc: " in text
    assert run("decompress", out, "-o", tmp_path / "out", "-q").exit_code == 0
    stored = {c["path"]: c["error_cm"] for c in report["clips"]}
    for take in takes:
        errors, original_frames, decoded_frames = decoded_errors(take, tmp_path / "out" / take.name)
        assert np.array_equal(decoded_frames, original_frames)
        assert errors.mean() <= 1.0 and abs(errors.mean() - stored[take.name]) < 1e-3, take.name


def test_ppca_segmentation_cuts_where_the_behaviour_changes(shared_data):
    """segment.py (Barbic et al. via Hou et al. VI-B2): synthetic blocks, then run -> walk of subject 35."""
    from mocapzip.inputs.clip import load_clips
    from mocapzip.inputs.discover import find_clips
    from mocapzip.classes.segment import segment_take

    rng = np.random.default_rng(7)
    a = rng.normal(size=(400, 2)) @ rng.normal(size=(2, 10)) + 0.01 * rng.normal(size=(400, 10))
    b = rng.normal(size=(300, 2)) @ rng.normal(size=(2, 10)) + 3 + 0.01 * rng.normal(size=(300, 10))
    cuts = segment_take(np.vstack([a, b]), min_frames=120, horizon=60)
    assert len(cuts) == 3 and abs(cuts[1] - 400) <= 20
    assert segment_take(a, min_frames=120, horizon=60) == [0, 400]

    cmu = shared_data / "cmu" / "35"
    sources = find_clips([cmu / "35_17.amc", cmu / "35_18.amc", cmu / "35_01.amc"])
    clips = {c.source.relpath: c.poses for c in load_clips(sources, "normalised")}
    runs = np.vstack([clips["35_17.amc"], clips["35_18.amc"]])
    cuts = segment_take(np.vstack([runs, clips["35_01.amc"]]), min_frames=120, horizon=60)
    assert len(cuts) == 3 and abs(cuts[1] - len(runs)) <= 40, cuts
    assert segment_take(clips["35_01.amc"]) == [0, len(clips["35_01.amc"])]  # one walk: no cut

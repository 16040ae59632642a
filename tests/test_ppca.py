"""PPCA class models (thesis eq. 3.10 to 3.13) and `mcz classify` on real shared clips."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.stats import multivariate_normal

from mocapzip.cli.classify import classify as classify_command
from mocapzip.classes.by_name import class_in_table, read_class_table
from mocapzip.classes.ppca import (PpcaModel, classify, components_for_share, format_table, thesis_threshold,
                           train_models)


def low_rank_rows(rng, n=400, dim=8, rank=3, noise=0.05, offset=0.0):
    directions, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    latent = rng.normal(size=(n, rank)) * np.array([5.0, 2.0, 1.0][:rank])
    return offset + latent @ directions[:, :rank].T + noise * rng.normal(size=(n, dim))


def direct_log_density(rows, x, share=0.99):
    """Eq. 3.13 written out from numpy's covariance and eigendecomposition, pose by pose."""
    mean = rows.mean(axis=0)
    cov = np.cov(rows.T, bias=True)
    lam, v = np.linalg.eigh(cov)
    lam, v = lam[::-1], v[:, ::-1]
    q = int(np.argmax(np.cumsum(lam) / lam.sum() >= share - 1e-12)) + 1
    m = len(mean)
    rho = lam[q:].mean()
    out = []
    for pose in x:
        xc = pose - mean
        y = v[:, :q].T @ xc
        eps2 = xc @ xc - y @ y  # eq. 3.11
        log_numerator = -0.5 * np.sum(y**2 / lam[:q]) - eps2 / (2 * rho)  # log of exp(.) exp(.), no underflow
        denominator = (2 * np.pi) ** (q / 2) * np.prod(np.sqrt(lam[:q])) * (2 * np.pi * rho) ** ((m - q) / 2)
        out.append(log_numerator - np.log(denominator))
    return np.array(out), q, rho


def test_log_density_matches_eq_3_13_computed_directly():
    rng = np.random.default_rng(0)
    rows = low_rank_rows(rng)
    model = PpcaModel.fit(rows)
    test = np.vstack([rows[:5], low_rank_rows(rng, n=5, noise=0.3)])
    expected, q, rho = direct_log_density(rows, test)
    assert model.q == q == 3
    assert model.rho == pytest.approx(rho, rel=1e-9)
    np.testing.assert_allclose(model.log_density(test), expected, rtol=1e-9)


def test_ppca_is_the_gaussian_with_rho_in_the_minor_directions():
    """Eq. 3.13 is the density of N(mean, V_Q L_Q V_Q^T + rho (I - V_Q V_Q^T)): check against scipy."""
    rng = np.random.default_rng(1)
    rows = low_rank_rows(rng, dim=6, rank=2, noise=0.2, offset=100.0)
    model = PpcaModel.fit(rows, variance_share=0.9)
    v = model.components
    cov = v @ np.diag(model.variances) @ v.T + model.rho * (np.eye(6) - v @ v.T)
    x = rows[::37] + rng.normal(size=(len(rows[::37]), 6))
    np.testing.assert_allclose(model.log_density(x), multivariate_normal(model.mean, cov).logpdf(x), rtol=1e-7)
    # with every component kept, it is the sample Gaussian itself
    full = PpcaModel.fit(rows, q=6)
    np.testing.assert_allclose(full.log_density(x),
                               multivariate_normal(rows.mean(axis=0), np.cov(rows.T, bias=True)).logpdf(x), rtol=1e-6)


def test_q_holds_the_variance_share_and_stats_give_the_mean_density():
    assert components_for_share(np.array([90.0, 9.0, 0.9, 0.1]), 0.99) == 2
    assert components_for_share(np.array([90.0, 9.0, 0.9, 0.1]), 0.995) == 3
    assert components_for_share(np.array([90.0, 9.0, 0.9, 0.1]), 0.5) == 1
    assert components_for_share(np.zeros(3), 0.99) == 1
    rng = np.random.default_rng(2)
    rows = low_rank_rows(rng)
    model = PpcaModel.fit(rows[:200])
    other = rows[200:] + 0.5
    centred = other - other.mean(axis=0)
    from_stats = model.mean_log_density_from_stats(len(other), other.mean(axis=0), centred.T @ centred)
    assert from_stats == pytest.approx(model.log_density(other).mean(), rel=1e-9)


def test_degenerate_class_still_has_a_finite_density():
    rows = np.tile(np.arange(5.0), (10, 1))
    rows[:, 0] += np.linspace(0, 1, 10)  # one direction of variance only
    model = PpcaModel.fit(rows)
    assert model.rho > 0 and np.all(np.isfinite(model.log_density(rows + 0.01)))


def test_thesis_threshold_makes_the_table_sum_to_columns_times_100():
    rng = np.random.default_rng(3)
    scores = [rng.normal(size=(50, 3)) + i for i in range(3)] + [rng.normal(size=(80, 3))]
    groups = ["a", "b", "c", "a"]
    t = thesis_threshold(scores, groups)
    total = 0.0
    for g in set(groups):
        pooled = np.vstack([s for s, gg in zip(scores, groups) if gg == g])
        total += (pooled > t).mean(axis=0).sum()
    assert total == pytest.approx(3.0, abs=0.02)


@pytest.fixture(scope="module")
def walk_run(shared_data):
    """Short real clips: walks of subject 07, runs of 09 (training), walks and runs of 35 (test)."""
    from mocapzip.inputs.clip import load_clips
    from mocapzip.inputs.discover import find_clips
    from mocapzip.classes.ppca import classification_poses

    cmu = shared_data / "cmu"
    files = {"train": [cmu / "07" / "07_01.amc", cmu / "07" / "07_02.amc", cmu / "09" / "09_01.amc", cmu / "09" / "09_02.amc"],
             "test": [cmu / "35" / "35_01.amc", cmu / "35" / "35_02.amc", cmu / "35" / "35_17.amc", cmu / "35" / "35_18.amc"]}
    out = {}
    for part, paths in files.items():
        sources = find_clips(paths)
        clips = load_clips(sources, "normalised")
        out[part] = {c.source.relpath: classification_poses(c) for c in clips}
    labels = read_class_table(shared_data / "MANIFEST.tsv")
    truth = {name: labels[f"cmu/{name[:2]}/{name}"] for part in out.values() for name in part}
    return out, truth, files


def test_classifier_separates_walk_and_run_of_another_subject(walk_run):
    poses, truth, _ = walk_run
    models = train_models({k: truth[k] for k in poses["train"]}, poses["train"])
    assert list(models) == ["run", "walk"]
    report = classify(models, poses["test"], truth)
    table = np.array(report["table"]["share"])
    assert report["table"]["rows"] == ["run", "walk"] and report["table"]["columns"] == ["run", "walk"]
    assert table.sum() == pytest.approx(200.0, abs=1.0)  # the automatic threshold: columns x 100 %
    assert np.all(np.diag(table) > 50) and np.all(table[~np.eye(2, dtype=bool)] < 20)
    assert report["clip_accuracy"] == 100.0 and report["pose_accuracy"] > 90
    assert all(c["best"] == c["class"] for c in report["clips"])
    assert "run class" in format_table(report)


def test_label_lookup_prefers_the_longest_matching_path(shared_data):
    from mocapzip.inputs.discover import find_clips

    table = {"07_01.amc": "other", "cmu/07/07_01.amc": "walk"}
    (source,) = find_clips([shared_data / "cmu" / "07" / "07_01.amc"])
    assert class_in_table(source, table) == "walk"
    assert class_in_table(source, {"cmu/09/09_01.amc": "run"}) is None


def test_classify_command_json_and_table(walk_run, shared_data, tmp_path):
    _, _, files = walk_run
    labels = tmp_path / "labels.csv"
    labels.write_text("07_01.amc,walk\n07_02.amc,walk\n09_01.amc,run\n09_02.amc,run\n35_01.amc,walk\n35_17.amc,run\n")
    train = [str(p) for p in files["train"]]
    test = [str(files["test"][0]), str(files["test"][2])]
    result = CliRunner().invoke(classify_command, ["--train", str(labels), *train, "--test", *test, "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert report["representation"] == "normalised" and report["train"]["clips"] == 4
    assert [c["best"] for c in report["clips"]] == ["walk", "run"]
    result = CliRunner().invoke(classify_command, ["--train", str(labels), *train, "--test", *test,
                                                   "-r", "aligned", "--threshold", "-2000"])
    assert result.exit_code == 0, result.output
    assert "threshold -2000.0" in result.output and "walk class" in result.output
    result = CliRunner().invoke(classify_command, ["--train", str(labels), *train, "--test", *test, "--segment", "--json"])
    assert result.exit_code == 0, result.output
    assert [c["path"] for c in json.loads(result.output)["clips"]] == ["35_01.amc", "35_17.amc"]  # short: not cut
    result = CliRunner().invoke(classify_command, ["--train", str(labels), *train, "--test", *test, "--threshold", "x"])
    assert result.exit_code == 2
    labels.write_text("07_01.amc,walk\n")
    result = CliRunner().invoke(classify_command, ["--train", str(labels), *train, "--test", *test])
    assert result.exit_code == 1 and "has no class" in result.output

"""Physics-based features (mocapzip.motion.physics): segments found on every family of the shared
data, the centre of mass falling at g, and features blind to where the body is and which way it faces."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.formats.bvh import read_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.bvh_skeleton import bvh_skeleton
from mocapzip.motion.kinematics import forward
from mocapzip.motion.physics import TRUNK_MASS, body_segments, physics_features
from mocapzip.motion.skeleton import SkeletonModel, side_of

SKELETONS = {"cmu": "cmu/07/07.asf", "hdm05": "hdm05/bd/HDM_bd.asf", "bandai": "bvh-bandai/dataset-1_walk_normal_001.bvh",
             "cmu-bvh": "cmu-bvh/10/10_01.bvh"}


def model_of(shared_data, relative: str) -> SkeletonModel:
    path = shared_data / relative
    if path.suffix == ".bvh":
        return bvh_skeleton(read_bvh(path).joints, None).model
    return SkeletonModel.from_asf(read_asf(path))


@pytest.mark.parametrize("family", SKELETONS)
def test_every_family_has_its_segments_and_the_whole_mass(shared_data, family):
    model = model_of(shared_data, SKELETONS[family])
    segments = body_segments(model)
    assert segments.masses.sum() + TRUNK_MASS == pytest.approx(1.0)
    assert len(segments.bones) == (15 if family in ("cmu", "hdm05") else 14)  # the ASFs have two neck bones
    named = [model.names[segments.bones[k]].lower() for k in segments.momentum]
    assert sum("hand" in n for n in named[:2]) == 2 and sum("foot" in n for n in named[2:]) == 2
    lefts = [n.startswith("l") or n.endswith("_l") for n in named]
    assert lefts == [True, False, True, False]  # left, then right: CMU's BVH lists the right first
    upper_arms = [model.names[j].lower() for j in segments.shoulders]
    assert all(any(word in n for word in ("humerus", "shldr", "upperarm")) for n in upper_arms)


def test_a_skeleton_without_hands_is_refused(shared_data):
    model = model_of(shared_data, SKELETONS["cmu"])
    renamed = dataclasses.replace(model, names=tuple(n.replace("hand", "paw") for n in model.names))
    with pytest.raises(MocapFormatError, match="left and a right hand"):
        body_segments(renamed)


def test_the_centre_of_mass_of_a_falling_body_accelerates_at_g(shared_data):
    """Every angle 0 and the root on a parabola of g = 981 cm/s^2: the centre of mass accelerates at
    exactly (0, -g, 0) (central differences are exact on a parabola)."""
    model = model_of(shared_data, SKELETONS["cmu"])
    clip = read_amc(shared_data / "cmu/07/07_01.amc", read_asf(shared_data / SKELETONS["cmu"]))
    fps, frames = 120.0, 60
    values = np.zeros((frames, clip.values.shape[1]))
    t = np.arange(frames) / fps
    root = clip.bones.index("root")
    start = sum(clip.counts[:root])
    values[:, start:start + 3] = np.stack([30 * t, 100 - 0.5 * 981 * t ** 2, -20 * t], axis=1) / model.cm_per_unit
    pose = forward(model, values, clip)
    features = physics_features(model, pose.positions, pose.rotations, fps)
    np.testing.assert_allclose(features[2:-2, 0], np.tile([0.0, -981.0, 0.0], (frames - 4, 1)), atol=1e-6)


def test_features_do_not_see_where_the_body_is_or_which_way_it_faces(shared_data):
    model = model_of(shared_data, SKELETONS["cmu"])
    clip = read_amc(shared_data / "cmu/07/07_01.amc", read_asf(shared_data / SKELETONS["cmu"]))
    pose = forward(model, clip.values, clip)
    features = physics_features(model, pose.positions, pose.rotations, 120.0)
    turn = np.array([[np.cos(1.1), 0.0, -np.sin(1.1)], [0.0, 1.0, 0.0], [np.sin(1.1), 0.0, np.cos(1.1)]])
    moved = physics_features(model, pose.positions @ turn + [500.0, 0.0, -300.0], pose.rotations @ turn, 120.0)
    scale = np.abs(features).max(axis=0)
    np.testing.assert_allclose(moved / scale, features / scale, atol=1e-9)
    assert np.abs(features[:, 3:]).max() > 3 * np.abs(features[:, 1:3]).max()  # a walk: the feet swing more than the hands


@pytest.mark.parametrize(("name", "side"), [("lfoot", "l"), ("rtoes", "r"), ("Foot_L", "l"), ("Hand_R", "r"),
                                            ("LowerLeg_R", "r"), ("LeftFoot", "l"), ("RightHand", "r"),
                                            ("lHand", "l"), ("head", None)])
def test_the_side_a_limb_joint_is_on_comes_from_its_name(name, side):
    """A side suffix wins over a first letter: Bandai's LowerLeg_R is a right bone."""
    assert side_of(name) == side

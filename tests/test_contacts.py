"""Foot contacts and foot skate (`motion.contacts`) on real walks, and on hand-made slides."""

from __future__ import annotations

import numpy as np
import pytest

from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.contacts import (CONTACT_SPEED_CM_S, contacts, foot_joints, foot_skate, foot_strikes,
                                      horizontal_speed)
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel


@pytest.fixture(scope="module")
def walk(shared_data):
    model = SkeletonModel.from_asf(read_asf(shared_data / "cmu" / "07" / "07.asf"))
    motion = read_amc(shared_data / "cmu" / "07" / "07_01.amc")
    return model, forward(model, motion.values, motion).positions


def test_cmu_feet_are_the_toes_and_feet(walk):
    model, _ = walk
    assert sorted(model.names[j] for j in foot_joints(model)) == ["lfoot", "ltoes", "rfoot", "rtoes"]


def test_a_walk_plants_each_foot_in_turn(walk):
    """In a walk each foot is planted for a good part of the stride, the two alternating; only
    foot joints are ever planted, and only while nearly still."""
    model, positions = walk
    planted = contacts(model, positions, 120.0)
    left = planted[:, [model.index["lfoot"], model.index["ltoes"]]].any(axis=1)
    right = planted[:, [model.index["rfoot"], model.index["rtoes"]]].any(axis=1)
    assert 0.2 < left.mean() < 0.8 and 0.2 < right.mean() < 0.8
    assert (left | right).mean() > 0.5 and (left & right).mean() < 0.5
    assert not planted[:, np.setdiff1d(np.arange(len(model.names)), foot_joints(model))].any()
    assert np.all(horizontal_speed(positions, 120.0)[planted] < CONTACT_SPEED_CM_S)


def test_foot_skate_is_the_extra_slide_of_planted_feet(walk):
    model, positions = walk
    planted = contacts(model, positions, 120.0)
    assert foot_skate(positions, positions, planted, 120.0) == 0.0
    sliding = positions.copy()
    sliding[:, :, 0] += 0.1 * np.arange(len(positions))[:, None]  # everything drifts 0.1 cm a frame: 12 cm/s
    skate = foot_skate(positions, sliding, planted, 120.0)
    assert 0 < skate <= 12.0 + 1e-9
    assert foot_skate(positions, sliding, np.zeros_like(planted), 120.0) == 0.0


@pytest.mark.parametrize("actor", ["bd", "bk", "dg"])
def test_strikes_of_a_jog_of_four_steps_alternate_from_the_right_foot(shared_data, actor):
    """HDM05's jogLeftCircle4StepsRstart: four steps, right foot first, each foot in turn."""
    path = next((shared_data / "hdm05" / actor).glob("*jogLeftCircle4StepsRstart*"))
    skeleton = read_asf(next(path.parent.glob("*.asf")))
    model = SkeletonModel.from_asf(skeleton)
    motion = read_amc(path, skeleton)
    strikes = foot_strikes(model, forward(model, motion.values, motion).positions, 120.0)
    order = [side for _, side in sorted((frame, side) for side, frames in strikes.items() for frame in frames)]
    assert order == ["r", "l", "r", "l"]

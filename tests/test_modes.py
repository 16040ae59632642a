"""Natural modes from clip paths (`--modes`, mocapzip.classes.modes): which classes fill a grid."""

from __future__ import annotations

import pytest

from mocapzip.classes.modes import compiled_modes, natural_modes

STYLE_TAKE = r"_(?P<style>[a-z]+)_(?P<take>[0-9]+)[.]bvh$"


def test_clips_that_fill_the_grid_get_their_places_in_sorted_levels():
    paths = ["walk_proud_002.bvh", "walk_angry_001.bvh", "walk_proud_001.bvh", "walk_angry_002.bvh"]
    grid = natural_modes(paths, STYLE_TAKE)
    assert grid.modes == ("style", "take")
    assert grid.levels == (("angry", "proud"), ("001", "002"))
    assert grid.at == ((1, 1), (0, 0), (1, 0), (0, 1))


def test_a_mode_of_one_level_is_left_out():
    grid = natural_modes(["bow_proud_001.bvh", "bow_angry_001.bvh"], STYLE_TAKE)
    assert grid.modes == ("style",) and grid.levels == (("angry", "proud"),) and grid.at == ((1,), (0,))


@pytest.mark.parametrize("paths", [
    ["walk_proud_001.bvh", "walk_angry_001.bvh", "walk_proud_002.bvh"],  # a place of the grid has no clip
    ["walk_proud_001.bvh", "walk_angry_001.bvh", "bow.bvh"],  # a path the pattern does not match
    ["walk_proud_001.bvh", "walk_proud_001.bvh"],  # one level on every mode: no grid at all
    ["a/walk_proud_001.bvh", "b/walk_proud_001.bvh", "walk_angry_001.bvh", "walk_angry_002.bvh"],  # two at one place
    [],
])
def test_clips_that_fill_no_grid_have_none(paths):
    assert natural_modes(paths, STYLE_TAKE) is None


@pytest.mark.parametrize("pattern, problem", [
    ("HDM_([a-z]+)_", "names 0 groups"),
    ("(?P<actor>[a-z", "not a regular expression"),
    ("".join(f"(?P<m{k}>x)" for k in range(9)), "names 9 groups"),
    ("(?P<actor>x)" + "y" * 1000, "more than 1,000"),
])
def test_a_pattern_without_named_groups_or_not_a_pattern_is_refused_in_one_line(pattern, problem):
    with pytest.raises(ValueError, match=problem):
        compiled_modes(pattern)

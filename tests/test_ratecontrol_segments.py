"""A take cut by --segment is held to -e once its segments are joined (`ratecontrol.segments`)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from mocapzip.ratecontrol import segments as rc_segments
from mocapzip.ratecontrol.max_error import TargetError
from mocapzip.ratecontrol.segments import TIGHTENINGS, SegmentCoding, joined_take
from mocapzip.ratecontrol.target import Bounds, CodingTarget


class _Take:
    """A take whose joined decodes score the given mean errors, one per check."""

    def __init__(self, errors):
        self.errors, self.checks = list(errors), 0
        self.motion = SimpleNamespace(n_frames=10)
        self.source = SimpleNamespace(motion="take.amc")

    def final_check(self, *joined):
        error = self.errors[min(self.checks, len(self.errors) - 1)]
        self.checks += 1
        return SimpleNamespace(error=(error, 2 * error), twists={})


@pytest.fixture
def coded(monkeypatch):
    """The coding and decoding stand-ins; returns the aims the segments were coded again at."""
    aims = []
    monkeypatch.setattr(rc_segments.CodedClip, "from_payload", staticmethod(lambda *a: None))
    monkeypatch.setattr(rc_segments, "reconstruct", lambda *a: None)
    monkeypatch.setattr(rc_segments, "join_decoded", lambda *a: ())
    monkeypatch.setattr(rc_segments, "achieved", lambda take, check, bounds: (None, None))

    def code_clip(clip, basis, transform, aim, dead_zone, split):
        aims.append(aim)
        return SimpleNamespace(coded=SimpleNamespace(payload=lambda coder: b"again"), error=(aim, aim))
    monkeypatch.setattr(rc_segments, "code_clip", code_clip)
    return aims


def _joined(take):
    target = CodingTarget(error_cm=1.0, bounds=Bounds(), plant_feet=False, transform={}, dead_zone=0.2,
                          basis_precision=0.1)
    segment = SegmentCoding(0, 10, 10, SimpleNamespace(q=1), b"first", (0.9, 2.0))
    return joined_take(take, [segment], [None], None, target)


def test_a_joined_take_within_the_target_is_kept_though_a_tighter_aim_coded_it(coded):
    """1.05 cm misses 1 cm; coded again at 0.9 it joins to 0.95 cm: within the user's 1 cm, so it is
    kept (it was once held to the 0.9 cm aim, coded again and again, and refused, "segments joined to
    0.95 cm, above 1 cm")."""
    joined = _joined(_Take([1.05, 0.95]))
    assert coded == [pytest.approx(0.9)]
    assert joined.streams == (b"again",)


def test_a_joined_take_that_never_meets_the_target_is_refused_after_every_tightening(coded):
    with pytest.raises(TargetError, match=r"joined to 1\.0500 cm, above 1 cm"):
        _joined(_Take([1.05]))
    assert len(coded) == TIGHTENINGS

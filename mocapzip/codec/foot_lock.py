"""The foot lock: planted feet held still by the decoder (`compress --plant-feet`, format 9).

The codec bounds errors, not speeds. A planted foot whose small error changes from frame to
frame slides across the floor (foot skate, `motion.contacts`), and patching single frames only
adds jitter (docs/fidelity.md). So for each *stance*, a run of frames in which the source
plants a foot joint, the archive stores where it is and nothing else: which foot joint, its
first frame and its length. The decoder holds that joint at its own decoded mean position
over the stance, easing in and out over RAMP frames on either side, and reaches it by turning
the leg's rotation channels (inverse kinematics: `compiled.plant_feet`). A stance costs a few
bytes; which stances to store, and whether the lock is worth it, is the encoder's choice
(`ratecontrol.planted_feet`).

Stream `plant/NNNNN` (docs/format.md): one "context" matrices stream (`codec.entropy.coefficients`)
of one (S, 3) matrix, S = the row's `planted_stances`: per stance, sorted by foot joint and then
by frame, the foot joint's index among `contacts.foot_joints`, its gap after the previous stance
of the same joint ends (the first's: its first frame), and its length in frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapzip.codec.entropy.coefficients import decode_matrices, encode_matrices
from mocapzip.motion import compiled
from mocapzip.motion.contacts import FOOT_NAME, foot_joints

RAMP = 8  # frames on either side of a stance over which the lock eases in and out, at most
ROUNDS = 3  # Gauss-Newton rounds per frame (each about 100x closer: targets are a few cm away)
DAMPING = 4.0  # cm^2 per rad^2 of leg rotation: the least change of the leg that reaches the target


@dataclass(frozen=True)
class Stances:
    """Runs of frames in which one foot joint is held still: what `plant/NNNNN` stores."""

    feet: np.ndarray  # (S,) index among `foot_joints(model)`
    first: np.ndarray  # (S,) first frame within the clip
    frames: np.ndarray  # (S,) length, >= 1

    @classmethod
    def of(cls, runs: list[tuple[int, int, int]]) -> "Stances":
        """From (foot index, first frame, frames) runs, in any order."""
        runs = sorted(runs)
        return cls(*(np.array([run[i] for run in runs], np.int64) for i in range(3)))

    def __len__(self) -> int:
        return len(self.feet)

    def subset(self, keep: np.ndarray) -> "Stances":
        return Stances(self.feet[keep], self.first[keep], self.frames[keep])

    def _after_previous(self) -> tuple[np.ndarray, np.ndarray]:
        """(S - 1,) whether each stance but the first is of the previous one's joint, and the
        frames from the previous one's end to its start."""
        return self.feet[1:] == self.feet[:-1], self.first[1:] - (self.first + self.frames)[:-1]

    def eases(self) -> tuple[np.ndarray, np.ndarray]:
        """(S,) frames over which each stance eases in, and out: RAMP, or half the frames between
        it and its joint's stance before (after), rounded down, if fewer. So the windows of one
        joint's stances never overlap, and its target never jumps from one anchor to the next."""
        same, gaps = self._after_previous()
        between = np.full(len(self) + 1, RAMP, np.int64)  # [i]: the ease between stances i - 1 and i
        between[1:-1] = np.where(same, np.minimum(RAMP, gaps // 2), RAMP)
        return between[:-1], between[1:]

    def windows(self, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
        """(S,) first and past-the-last frame each stance moves: itself and its eases, within the clip."""
        ease_in, ease_out = self.eases()
        return np.maximum(self.first - ease_in, 0), np.minimum(self.first + self.frames + ease_out, n_frames)

    def payload(self) -> bytes:
        same, gaps = self._after_previous()
        stored_gaps = np.r_[self.first[:1], np.where(same, gaps, self.first[1:])]
        return encode_matrices([np.column_stack([self.feet, stored_gaps, self.frames])])

    @classmethod
    def from_payload(cls, blob: bytes, count: int, n_frames: int, n_feet: int) -> "Stances":
        """The `count` stances (its row's `planted_stances`) of a clip of `n_frames` with `n_feet`
        foot joints. The blob may come from anyone: feet, order and frames are checked."""
        (matrix,) = decode_matrices(blob, [(count, 3)])
        feet, gaps, frames = matrix[:, 0], matrix[:, 1], matrix[:, 2]
        if np.any(feet < 0) or np.any(feet >= n_feet) or np.any(np.diff(feet) < 0):
            raise ValueError(f"stance feet must be increasing indices below the skeleton's {n_feet} foot joints")
        if np.any(gaps < 0) or np.any(gaps > n_frames) or np.any(frames < 1) or np.any(frames > n_frames):
            raise ValueError(f"stance gaps must be within 0..{n_frames} and lengths within 1..{n_frames}")
        first = np.empty(count, np.int64)
        end = 0
        for s in range(count):  # at most 3 n_frames: no overflow
            end = 0 if s == 0 or feet[s] != feet[s - 1] else end
            first[s] = end + gaps[s]
            end = first[s] + frames[s]
            if end > n_frames:
                raise ValueError(f"a stance ends at frame {end}, past the clip's {n_frames} frames")
        return cls(feet.astype(np.int64), first, frames.astype(np.int64))


@dataclass(frozen=True)
class Leg:
    """The foot joints one hip moves, and what the lock may turn to reach them."""

    feet: np.ndarray  # joint indices
    above: np.ndarray  # the root and the joints down to the hip's parent, parents first
    chain: np.ndarray  # the joints from the hip down to those feet, parents first
    dofs: np.ndarray  # the rotation columns of the chain's joints in the clip's layout


def legs(model, tail) -> list[Leg]:
    """Each foot joint's leg: its joint and ancestors up to the second one above the foot with
    rotation channels (CMU: toes and foot, then tibia and femur; not the root, which moves the
    whole body). Foot joints that reach the same top joint share a leg."""
    rotates = [tail.first_column[j] >= 0 and any(tail.channel_kind[j, k] == 0 for k in range(tail.n_channels[j]))
               for j in range(model.n_joints)]
    chains: dict[int, list[tuple[int, list[int]]]] = {}
    for foot in foot_joints(model):
        path, above, j = [], 0, int(foot)
        while j > 0 and above < 2:
            path.append(j)
            above += rotates[j] and not FOOT_NAME.search(model.names[j])
            j = int(model.parents[j])
        if path:
            chains.setdefault(path[-1], []).append((int(foot), path))
    out = []
    for top, members in sorted(chains.items()):
        chain = sorted({j for _, path in members for j in path})
        dofs = [tail.first_column[j] + k for j in chain if tail.first_column[j] >= 0
                for k in range(tail.n_channels[j]) if tail.channel_kind[j, k] == 0]
        above, j = [], int(model.parents[top])
        while j >= 0:
            above.insert(0, j)
            j = int(model.parents[j])
        if dofs:
            out.append(Leg(np.array([foot for foot, _ in members], np.int64), np.array(above, np.int64),
                           np.array(chain, np.int64), np.array(dofs, np.int64)))
    return out


def hold(values: np.ndarray, stances: Stances, model, tail) -> None:
    """The foot lock, in place on decoded channel `values` (frames x C, before the writer rounds
    them): each stance's joint held at its mean position over the stance (positions from
    `values` as given), eased in and out (`Stances.eases`; `compiled.plant_feet` solves each
    leg); `tail`: the clip's DecodeTail."""
    if not len(stances):
        return
    n_frames = len(values)
    feet = foot_joints(model)
    lo, hi = stances.windows(n_frames)
    held = np.unique(np.concatenate([np.arange(a, a + n) for a, n in zip(stances.first, stances.frames)]))
    row_of = np.full(n_frames, -1, np.int64)
    row_of[held] = np.arange(len(held))
    decoded = tail.positions(values[held])  # (held frames, J, 3), before any leg moves: the anchors
    weight = np.zeros((len(feet), n_frames))  # the windows of one joint's stances never overlap
    anchor = np.zeros((len(feet), n_frames, 3))
    ease_in, ease_out = stances.eases()
    for s in range(len(stances)):
        f, first, end = int(stances.feet[s]), int(stances.first[s]), int(stances.first[s] + stances.frames[s])
        weight[f, first:end] = 1.0
        weight[f, lo[s]:first] = _ramp(int(ease_in[s]))[ease_in[s] - (first - lo[s]):]  # cut at frame 0
        weight[f, end:hi[s]] = _ramp(int(ease_out[s]))[::-1][:hi[s] - end]
        anchor[f, lo[s]:hi[s]] = decoded[row_of[first:end], feet[f]].mean(axis=0)
    for leg in legs(model, tail):
        index = np.searchsorted(feet, leg.feet)
        frames = np.flatnonzero(np.any(weight[index] > 0, axis=0))
        if not frames.size:
            continue
        compiled.plant_feet(values, frames, leg.feet, leg.above, leg.chain, leg.dofs,
                            np.ascontiguousarray(weight[index][:, frames].T),
                            np.ascontiguousarray(anchor[index][:, frames].transpose(1, 0, 2)), DAMPING, ROUNDS,
                            *tail.fk_tables())


def _ramp(length: int) -> np.ndarray:
    """The weights of an ease of `length` frames, rising towards the stance: 0.5 - 0.5 cos(pi i / (length + 1))."""
    return 0.5 - 0.5 * np.cos(np.pi * np.arange(1, length + 1) / (length + 1))

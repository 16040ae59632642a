"""Joint errors of BVH -> ASF/AMC conversion (`mcz convert`, docs/bvh.md "Converting") on every shared BVH file.

    python benchmarks/convert_errors.py

Converts each clip of cmu-bvh and bvh-bandai that converts (4 of Bandai's have an extra root that
moves) into a temporary folder, reads the ASF/AMC back with mcz and with tests/test_convert.py's
`plain_positions` (a reader that turns x, then y, then z whatever the dof line's order), and
prints per set how far the joints are from where the BVH puts them (the mean over clips of each
clip's mean, and the largest), how far the two readers are apart, the AMC files' significant
digits (`convert.AMC_DIGITS`), and the clips whose AMC angles change more from one frame to the
next (modulo 360 degrees) than their BVH's.
"""

from __future__ import annotations

import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from mocapzip.convert import convert
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.formats.bvh import read_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.bvh_skeleton import bvh_skeleton, file_positions, point_names
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_convert import plain_positions  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def clip_measures(path: Path, folder: Path) -> dict:
    """One clip converted in `folder`: mcz's and the plain reader's (frames, joints) cm from the BVH's
    joints, the largest distance between the two readers, the AMC's significant digits, and the
    largest change of an angle from one frame to the next (modulo 360 degrees) in the AMC and in
    the BVH."""
    convert([path], folder)
    asf, amc = folder / f"{path.stem}.asf", folder / f"{path.stem}.amc"
    skeleton = read_asf(asf)
    motion = read_amc(amc, skeleton)
    mcz = forward(SkeletonModel.from_asf(skeleton), motion.values, motion).positions
    _, plain = plain_positions(asf, amc)
    source = read_bvh(path)
    at = {name: k for k, name in enumerate(point_names(source.joints))}
    expected = file_positions(source)[:, [at[point] for point in bvh_skeleton(source.joints, None).model.points]]
    amc_angles = [c[0] == "r" for bone in motion.bones for c in skeleton.dof_of(bone)]
    bvh_angles = [c.endswith("rotation") for joint in source.joints for c in joint.channels]
    return {"mcz": np.linalg.norm(mcz - expected, axis=-1), "plain": np.linalg.norm(plain - expected, axis=-1),
            "apart": float(np.linalg.norm(plain - mcz, axis=-1).max()), "digits": motion.style.digits,
            "amc step": _largest_step(motion.values[:, amc_angles]), "bvh step": _largest_step(source.values[:, bvh_angles])}


def _largest_step(angles: np.ndarray) -> float:
    """The largest change of an angle (degrees) from one frame to the next, modulo 360 degrees."""
    return float(np.abs((np.diff(angles, axis=0) + 180) % 360 - 180).max(initial=0.0))


def main() -> None:
    for name in ("cmu-bvh", "bvh-bandai"):
        clips, refused = [], 0
        for path in sorted((DATA / name).rglob("*.bvh")):
            with tempfile.TemporaryDirectory() as folder:
                try:
                    clips.append(clip_measures(path, Path(folder)))
                except MocapFormatError:
                    refused += 1
        digits = Counter(clip["digits"] for clip in clips)
        print(f"{name}: {len(clips)} clips ({refused} refused), AMC digits {dict(sorted(digits.items()))}")
        for reader in ("mcz", "plain"):
            print(f"  {reader:5} reader: joints {np.mean([clip[reader].mean() for clip in clips]):.2g} cm from the "
                  f"BVH's on average, at most {max(clip[reader].max() for clip in clips):.2g} cm")
        print(f"  the two readers at most {max(clip['apart'] for clip in clips):.2g} cm apart")
        steps = sorted((clip["amc step"], clip["bvh step"]) for clip in clips if clip["amc step"] > clip["bvh step"])
        largest = "".join(f", ({a:.0f}, {b:.0f}) degrees" for a, b in steps[-4:])
        print(f"  clips whose AMC angles change more in a frame than their BVH's: {len(steps)}{largest}")


if __name__ == "__main__":
    main()

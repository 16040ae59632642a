"""The universal body the `scaled` and `normalised` representations map every clip to.

Thesis 3.2.1: universal bone lengths are those of one arbitrarily chosen ASF of
the database. Here: CMU subject 07 (cmu/07/07.asf), lengths in cm
(length x 2.54 / 0.45). The universal height is the thesis's height of that
skeleton, so both representations agree on one body.
"""

from __future__ import annotations

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel

UNIVERSAL_LENGTHS_CM = {
    "lhipjoint": 15.1375,
    "lfemur": 39.0856,
    "ltibia": 41.7975,
    "lfoot": 11.2893,
    "ltoes": 5.6818,
    "rhipjoint": 14.4792,
    "rfemur": 40.3851,
    "rtibia": 40.2420,
    "rfoot": 11.9191,
    "rtoes": 5.9602,
    "lowerback": 12.6439,
    "upperback": 12.4247,
    "thorax": 12.4919,
    "lowerneck": 8.2594,
    "upperneck": 8.5130,
    "head": 8.6053,
    "lclavicle": 19.1177,
    "lhumerus": 28.0391,
    "lradius": 18.9513,
    "lwrist": 9.4757,
    "lhand": 4.4984,
    "lfingers": 3.6268,
    "lthumb": 5.2073,
    "rclavicle": 19.2964,
    "rhumerus": 29.4560,
    "rradius": 18.9938,
    "rwrist": 9.4969,
    "rhand": 3.5021,
    "rfingers": 2.8235,
    "rthumb": 4.0539,
}

# The thesis's height: left leg from the hip joint down plus the spine up to the head.
HEIGHT_BONES = ("lhipjoint", "lfemur", "ltibia", "lowerback", "upperback", "thorax", "lowerneck", "upperneck", "head")
UNIVERSAL_HEIGHT_CM = sum(UNIVERSAL_LENGTHS_CM[name] for name in HEIGHT_BONES)


def skeleton_height(model: SkeletonModel) -> float:
    """Height in cm: the sum of the HEIGHT_BONES lengths. Skeletons without those
    names (Vicon Blade) use the vertical extent of their base pose instead, which
    on CMU skeletons is about 5% below the bone sum (feet and hip offsets differ)."""
    if all(name in model.index for name in HEIGHT_BONES):
        return float(sum(model.lengths[model.index[name]] for name in HEIGHT_BONES))
    up = model.base_positions()[:, 1]
    return float(up.max() - up.min())


def universal_lengths(model: SkeletonModel) -> np.ndarray:
    """(J,) universal length of each joint's bone; the clip's own length for bones the
    table does not know, and for short bones (their direction is stored, not measured)."""
    return np.array(
        [
            UNIVERSAL_LENGTHS_CM.get(name, length) if j > 0 and not model.short[j] else length
            for j, (name, length) in enumerate(zip(model.names, model.lengths))
        ]
    )

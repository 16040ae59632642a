"""A field a format version added is refused in an archive of an older version, as that
version's readers refused it (`legacy.FIELDS_ADDED_IN`), and accepted from its version on."""

from __future__ import annotations

import copy
import re
from pathlib import Path

import pytest

from mocapzip.archive import Archive
from mocapzip.archive.meta import validate
from mocapzip.formats.mcz import FORMAT_VERSION, ArchiveError
from mocapzip.legacy import FIELDS_ADDED_IN

GOLDEN = Path(__file__).parent / "golden"
EXAMPLES = {"coefficient_coder": "context", "axes_from_positions": True, "twist_flips": {"lthumb": [0, 1]},
            "max_error_cm": 10.0, "p99_error_cm": 1.0, "patched_frames": 1, "contact_error_cm": 2.0,
            "repair_glitches": True, "repaired": [[1, 1, 1.0]], "fps_from_files": False, "fps": 200.0,
            "plant_feet": True, "planted_stances": 1, "model": "tensor", "modes": ["subject"],
            "levels": [["09", "64"]], "tensor_at": [0], "vertex_error_cm": 3.0, "shell_cm": 3.0,
            "max_vertex_error_cm": 2.0}
TENSOR = {"model", "modes", "levels", "tensor_at"}  # format 11's, which come together


def with_field(meta: dict, part: str, name: str, accepted: bool) -> dict:
    """`meta` with the field added; where it is `accepted`, with the fields that must come with it."""
    meta = copy.deepcopy(meta)
    if name in ("format", "bvh"):  # format 8's: a BVH skeleton, and its clips' text
        with Archive(GOLDEN / "lossy_v8.mcz") as newest:
            bvh_row = next(row for row in newest.clips if "bvh" in row)
            bvh_skeleton = newest.meta["skeletons"][bvh_row["skeleton"]]
        row = meta["clips"][0]
        if name == "format" or accepted:
            meta["skeletons"][row["skeleton"]] = dict(bvh_skeleton)
        if name == "bvh" or accepted:
            row["bvh"] = {"motion": f"MOTION\nFrames: {row['frames']}\nFrame Time: 0.01\n",
                          "style": bvh_row["bvh"]["style"]}
        if accepted:  # as a BVH clip's row has them
            row.update(header=[], first_frame=1, angle_unit="deg", path=row["path"].rsplit(".", 1)[0] + ".bvh")
        return meta
    if name in TENSOR and accepted:  # a tensor class as format 11's golden file has one, with its clips
        with Archive(GOLDEN / "lossy_v11.mcz") as newest:
            return copy.deepcopy(newest.meta)
    example = "(?P<subject>[0-9]+)" if (part, name) == ("settings", "modes") else EXAMPLES[name]
    (meta["settings"] if part == "settings" else meta[part][0])[name] = example
    return meta


@pytest.mark.parametrize("kind", ["lossy", "lossless"])
@pytest.mark.parametrize("version", range(1, FORMAT_VERSION + 1))
def test_each_golden_archive_meets_the_rules_of_its_version(kind, version):
    with Archive(GOLDEN / f"{kind}_v{version}.mcz") as archive:
        assert validate(archive.meta, archive._reader.names(), "x.mcz", version)


@pytest.mark.parametrize("added, part, name", [(v, p, n) for v, fields in FIELDS_ADDED_IN.items() for p, n in fields])
@pytest.mark.parametrize("version", range(1, FORMAT_VERSION + 1))
def test_a_field_is_refused_before_the_version_that_added_it(version, added, part, name):
    with Archive(GOLDEN / f"lossy_v{version}.mcz") as archive:
        meta, names = with_field(archive.meta, part, name, version >= added), archive._reader.names()
    if name in ("patched_frames", "planted_stances"):
        names = [*names, "patch/00000" if name == "patched_frames" else "plant/00000"]
    if name == "coefficient_coder":  # "context" codes without priors: a stream meta no longer claims
        names = [n for n in names if n != "priors"]
    if name in TENSOR and version >= added:
        with Archive(GOLDEN / "lossy_v11.mcz") as newest:
            names = newest._reader.names()
    if version < added:
        field = f"settings.{name}" if part == "settings" else f"{part}[0].{name}"
        with pytest.raises(ArchiveError, match=re.escape(f"meta: {field}: format {added} on")):
            validate(meta, names, "x.mcz", version)
    else:
        validate(meta, names, "x.mcz", version)

"""Write the codec's golden archives tests/golden/{lossy,lossless}_v{FORMAT_VERSION}.mcz.

Run by hand, only when the archive format changes (a new FORMAT_VERSION): each golden
file stays in the repository for good, so every future reader is tested against what
every past writer wrote. The script writes only the files that are missing. The inputs are two short real clips from ../shared/data: 09_01 and
09_02 up to version 3; from version 4, 09_01 and 64_01, whose left thumb needs twist flips
(`positions.TwistChoice`), so the golden file holds some. From version 5 the lossy file bounds
every joint at 3 cm (`--max-error`), so it holds frame patches; from version 6 it also bounds
planted feet at 2 cm (`--contact-error`) and repairs glitches (64_01's left thumb is beyond its
ASF limits), so its rows list repaired ranges. From version 8 a BVH clip joins them: Bandai's
dataset-1_walk-back_normal_001 (31 frames), whose extra root moves, so the lossy file holds an
extra_root stream. From version 9 the lossy file holds planted feet still (`--plant-feet`), so
its rows list stances and it holds plant streams. From version 10 the skeletons stream predicts
its numbers (layout 1); the encoder of that version codes the 31-frame BVH clip within 3 cm on
every joint without patches, so its patches are pinned down by versions 8 and 9 only. From
version 11 the lossy file uses `--model tensor` with 09_01 and 64_01 as two levels of a subject
mode: their class is stored as a tensor model (forced: on two clips the model never pays, and the
golden file is there to pin its streams down), and the BVH clip's class, which fills no grid,
as PCA. From version 12 the files are written with HDF5 1.10's object versions and their clips
tables list each clip's achieved errors; the inputs and settings are version 11's. From version 13
the lossy file also bounds every shell vertex (ACL's metric, `--max-vertex-error`) at 3 cm with a
2.5 cm shell, so its settings hold both and its rows their worst vertex, and its clips are coded
with version 13's default transform, `dct-edges`.

From version 12 it also writes example_v{FORMAT_VERSION}.mcz, the tiny archive docs/format.md shows
byte by byte ("Worked examples", checked by tests/test_format_examples.py): the first 4 frames of
09_01, coded as `channels` with the `identity` transform, so that each frame's values are the class
mean plus its coefficients times the basis.
"""

import tempfile
from pathlib import Path

from mocapzip.archive import Settings, compress
from mocapzip.formats.mcz import FORMAT_VERSION
from mocapzip.ratecontrol import tensor

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
GOLDEN = Path(__file__).parent / "golden"
INPUTS = [DATA / "cmu" / "09" / "09_01.amc", DATA / "cmu" / "64" / "64_01.amc",
          DATA / "bvh-bandai" / "dataset-1_walk-back_normal_001.bvh"]
EXAMPLE_FRAMES = 4


def example_clip(folder: Path) -> Path:
    """09_01.amc cut after its first EXAMPLE_FRAMES frames, beside its skeleton, in `folder`."""
    lines = (DATA / "cmu" / "09" / "09_01.amc").read_bytes().splitlines(keepends=True)
    end = lines.index(b"%d\n" % (EXAMPLE_FRAMES + 1))
    (folder / "09_01.amc").write_bytes(b"".join(lines[:end]))
    (folder / "09.asf").write_bytes((DATA / "cmu" / "09" / "09.asf").read_bytes())
    return folder


def write_once(name: str, inputs, settings: Settings) -> None:
    path = GOLDEN / f"{name}_v{FORMAT_VERSION}.mcz"
    if path.exists():
        print(f"{path} exists: golden files are never regenerated")
        return
    summary = compress(inputs, path, settings)
    print(f"wrote {path}: {summary['output_bytes']} bytes")


if __name__ == "__main__":
    # The lossy file uses the newest clip coder even where "auto" would not (two clips are too
    # few for priors to pay), so that the coder is what the golden file pins down.
    lossy = Settings(error_cm=1.0, max_error_cm=3.0, contact_error_cm=2.0, repair_glitches=True, plant_feet=True,
                     vertex_error_cm=3.0, shell_cm=2.5,
                     coefficient_coder="primed", model="tensor", modes=r"(?P<subject>[0-9]+)_01[.]amc$")
    tensor._pays = lambda tensor_bytes, best_bytes: True
    for name, settings in (("lossy", lossy), ("lossless", Settings(lossless=True))):
        write_once(name, INPUTS, settings)
    with tempfile.TemporaryDirectory() as folder:
        write_once("example", [example_clip(Path(folder))],
                   Settings(representation="channels", transform={"id": "identity"}))

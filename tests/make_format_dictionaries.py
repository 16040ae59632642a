"""Write the dictionaries of formats 7 and 10 (mocapzip/archive/dictionaries/). Run by hand, once.

They are format constants, like the golden files: never regenerated, since every format-7
archive's `meta` and `skeletons` streams refer to their bytes (docs/format.md, "Dictionaries").
This script says where they came from:

- `asf.txt`, skeleton templates: for each family of ASFs in ../shared/data (HDM05's three, CMU's
  thirteen), the text all its members share once numbers are set aside, with each number the
  value at least two members print there, or `0` where no two agree. So the templates hold a
  family's names, hierarchy, dofs, axes, limits and its common values, and no one subject's
  own measurements. CMU comes twice, with LF and with CRLF line ends (both occur); the most
  common family comes last, where zstd reaches it with the shortest offsets.
- `asf_means.txt` (format 10): `asf.txt` with, where no two members agree, the family's mean
  (6 significant digits) instead of 0. It is no dictionary of zstd's: an archive's first skeleton
  of a family has its numbers predicted from it (mocapzip/archive/skeletons.py).
- `meta.json`, a meta template: the meta of two one-clip archives written by this project's
  compress (a CMU clip, 124_02 part 1 from cmu-edited, and HDM05's first bd clip), which holds
  the keys, settings and the bone orders of both families.
"""

import json
import re
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "mocapzip" / "archive" / "dictionaries"
NUMBER = re.compile(rb"[-+]?[0-9][0-9.eE+-]*")


def family_template(texts: list[bytes], means: bool = False) -> bytes:
    """What the LF-ended `texts` share: the text between numbers (which must be the same in all),
    and each number the value two or more of them print there, else 0 (`means`: else their
    mean, printed to 6 significant digits)."""
    pieces = [NUMBER.split(text) for text in texts]
    numbers = [NUMBER.findall(text) for text in texts]
    if any(p != pieces[0] for p in pieces) or any(len(n) != len(numbers[0]) for n in numbers):
        sys.exit("the family's texts differ between their numbers: not one template")
    out = []
    for i, between in enumerate(pieces[0][:-1]):
        value, count = Counter(n[i] for n in numbers).most_common(1)[0]
        if count < 2:
            value = b"%.6g" % (sum(float(n[i]) for n in numbers) / len(numbers)) if means else b"0"
        out += [between, value]
    return b"".join([*out, pieces[0][-1]])


def asf_templates(means: bool = False) -> bytes:
    def family(pattern: str) -> bytes:
        return family_template([p.read_bytes().replace(b"\r\n", b"\n") for p in sorted(DATA.glob(pattern))], means)

    cmu = family("cmu/*/*.asf")
    return family("hdm05/*/*.asf").replace(b"\n", b"\r\n") + cmu + cmu.replace(b"\n", b"\r\n")


def asf_means() -> bytes:
    """Format 10's `asf_means.txt`: `asf.txt` with each number no two members agree on (0 there)
    the family's mean instead, what a first skeleton's numbers are predicted from."""
    return asf_templates(means=True)


def meta_template() -> bytes:
    from mocapzip.archive.reader import Archive
    from mocapzip.archive.settings import Settings
    from mocapzip.archive.writer import compress

    metas = []
    with tempfile.TemporaryDirectory() as tmp:
        for clip, asf in ((DATA / "cmu-edited/124/124_02_part1_frames1-699.amc", DATA / "cmu/07/07.asf"),
                          (sorted(DATA.glob("hdm05/bd/*.amc"))[0], DATA / "hdm05/bd/HDM_bd.asf")):
            folder = Path(tmp) / clip.stem
            folder.mkdir()
            (folder / clip.name).symlink_to(clip)
            compress([folder], folder / "a.mcz", Settings(error_cm=1.0, max_error_cm=10.0), asf=asf)
            with Archive(folder / "a.mcz") as archive:
                metas.append(json.dumps(archive.meta, sort_keys=True))
    return "".join(metas).encode()


if __name__ == "__main__":
    for name, make in (("asf.txt", asf_templates), ("meta.json", meta_template), ("asf_means.txt", asf_means)):
        path = OUT / name
        if path.exists():
            print(f"{path} exists: frozen with its format")
            continue
        data = make()
        path.write_bytes(data)
        print(f"wrote {path} ({len(data)} bytes)")

"""Seed 003's method in mcz: piecewise polynomial fits of the PCA curves (`-t poly`), and
tolerances weighted by singular value.

    python benchmarks/seed_poly.py [--data ../shared/data] [-j 2] [-e 1]
                                   [--knot-spacing 60,90,120,180,240] [--exponent -0.25,0,0.25,0.5]

Compresses the shared CMU set (compress's defaults otherwise, its --max-error included) and
prints two markdown tables of archive bytes:
- `-t poly` once per knot spacing (`PolyTransform.knot_spacing`), next to `-t dct`: how the
  default spacing was chosen;
- `-t dct` and `-t poly` once per tolerance exponent
  (`mocapzip.ratecontrol.encode.TOLERANCE_EXPONENT`: component j quantised
  (sigma_1 / sigma_j) ** exponent times coarser than the first; the page's weighting is a
  positive exponent, 0 is mcz's default).

The transforms side by side at 2, 1 and 0.5 cm, with errors measured end to end, are
`mcz bench ../shared/data/cmu --codec mcz -e 2 -e 1 -e 0.5 -t dct -t dwt -t poly`.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

from mocapzip.archive import Settings, compress  # noqa: E402
from mocapzip.cli.choices import max_error_cm  # noqa: E402
from mocapzip.ratecontrol import encode  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def archive_bytes(folder: Path, transform: dict, error: float, jobs: int, exponent: float = 0.0) -> dict:
    """compress's summary of the archive of `folder` with this transform and tolerance exponent."""
    encode.TOLERANCE_EXPONENT = exponent  # read by the encoder in this process and its forked workers
    settings = Settings(error_cm=error, max_error_cm=max_error_cm(None, error), transform=transform)
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the set's known glitches and golf_01's cut frame, said by compress
        return compress([folder], Path(tmp) / "db.mcz", settings, jobs=jobs)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help=f"the shared data folder (default {DATA})")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("-e", "--error", type=float, default=1.0, help="mean error target, cm (default 1)")
    parser.add_argument("--knot-spacing", default="60,90,120,180,240", help="spacings to try, frames")
    parser.add_argument("--exponent", default="-0.25,0,0.25,0.5", help="tolerance exponents to try")
    args = parser.parse_args(argv)
    folder = args.data / "cmu"

    def row(label: str, transform: dict, exponent: float, reference: int | None) -> int:
        summary = archive_bytes(folder, transform, args.error, args.jobs, exponent)
        size = summary["output_bytes"]
        versus = "" if reference is None else f"{100 * (size / reference - 1):+.1f} %"
        print(f"| {label} | {size:,} | {summary['bytes_per_frame']:.3f} | {versus} | {summary['seconds']:.0f} |",
              flush=True)
        return size

    print(f"Shared CMU set at {args.error:g} cm, `-j {args.jobs}`: knot spacing of `-t poly`\n")
    print("| transform | bytes | bytes/frame | vs dct | seconds |\n|---|---:|---:|---:|---:|")
    dct = row("dct", {"id": "dct"}, 0.0, None)
    for spacing in (int(s) for s in args.knot_spacing.split(",")):
        row(f"poly, knot spacing {spacing}", {"id": "poly", "knot_spacing": spacing}, 0.0, dct)

    print("\nTolerances weighted by singular value (exponent; 0 is the default)\n")
    print("| transform, exponent | bytes | bytes/frame | vs exponent 0 | seconds |\n|---|---:|---:|---:|---:|")
    for transform in ({"id": "dct"}, {"id": "poly", "knot_spacing": 120}):
        exponents = [float(x) for x in args.exponent.split(",")]
        base = row(f"{transform['id']}, 0", transform, 0.0, None) if 0.0 in exponents else None
        for exponent in exponents:
            if exponent != 0.0:
                row(f"{transform['id']}, {exponent:g}", transform, exponent, base)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

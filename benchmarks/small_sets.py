"""Small sets: what a few clips from many subjects cost, per `--classes` choice, and where the bytes go.

    python benchmarks/small_sets.py [-j N] [--classes pooled,subject,single,auto] [--pool-frames 4000,...]
                                    [--basis-precision 0.02,0.04,...] [-e CM]

Builds, in a temporary folder of links to ../shared/data/cmu (nothing is copied), three sets:
the first clip of each subject, the first two of each subject, and the whole shared set. Each
is compressed at 1 cm (`-e`; compress's defaults otherwise, its default --max-error included) once per `--classes` choice, and one
markdown row is printed per run: bytes per frame, and the fixed costs (skeletons, class
bases, meta, priors, container: `mocapzip.bench.runner.fixed_costs`) against the clips'
own streams. `--pool-frames` runs `pooled` once per threshold instead (`classes.by_name.POOL_FRAMES`:
subjects with fewer frames share a basis), which is how the default threshold was chosen
(docs/fixed_costs.md). `--basis-precision` runs the default classes once per
`Settings.basis_precision` (how finely class bases are stored), which is how its default was chosen. Issue 17's small-set target is 2.0 bytes/frame for 1-2 clips from each of 10
or more subjects.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

from mocapzip.archive import Archive, Settings, compress  # noqa: E402
from mocapzip.classes import by_name  # noqa: E402
from mocapzip.bench.runner import fixed_costs  # noqa: E402
from mocapzip.cli.choices import max_error_cm  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"


def linked_subset(root: Path, per_subject: int | None, data: Path = DATA) -> Path:
    """A folder under `root` of links to each CMU subject's ASF and its first `per_subject` AMCs (None: all)."""
    out = root / f"first_{per_subject or 'all'}"
    for subject in sorted(p for p in data.iterdir() if p.is_dir()):
        (out / subject.name).mkdir(parents=True)
        amcs = sorted(subject.glob("*.amc"))[:per_subject]
        for path in [*subject.glob("*.asf"), *amcs]:
            os.symlink(path, out / subject.name / path.name)
    return out


def run(runs: list[tuple[str, int, float]], jobs: int = 2, error: float = 1.0, show=print,
        data: Path = DATA) -> list[str]:
    """One markdown row per set and run, each (classes, pool threshold, basis precision), shown as
    it comes; returns the table (header included)."""
    variants = {field: len({run[k] for run in runs}) > 1 for k, field in ((1, "pool"), (2, "precision"))}
    rows = ["| set | clips | subjects | frames | --classes | bytes/frame | skeletons | bases | meta | priors | "
            "container | fixed share | clip streams and patches | seconds |",
            "|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        show(row)
    default_pool = by_name.POOL_FRAMES
    with tempfile.TemporaryDirectory() as work:
        try:
            for per_subject in (1, 2, None):
                inputs = linked_subset(Path(work), per_subject, data)
                for classes, pool_frames, precision in runs:
                    by_name.POOL_FRAMES = pool_frames
                    path = Path(work) / "set.mcz"
                    started = time.perf_counter()
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")  # glitches and a clip cut short: said by compress, not here
                        settings = Settings(classes=classes, error_cm=error, max_error_cm=max_error_cm(None, error),
                                            basis_precision=precision)
                        summary = compress([inputs], path, settings, jobs=jobs, force=True)
                    seconds = time.perf_counter() - started
                    with Archive(path) as archive:
                        fixed = fixed_costs(archive.stream_sizes(), summary["output_bytes"])
                        subjects = len(archive.meta["skeletons"])
                    total = sum(fixed.values())
                    name = f"first {per_subject} per subject" if per_subject else "whole shared set"
                    variant = (f" ({pool_frames:,})" if variants["pool"] else "") + \
                        (f" ({precision:g})" if variants["precision"] else "")
                    rows.append(f"| {name} | {summary['clips']} | {subjects} | {summary['frames']:,} | {classes}{variant} | "
                                f"{summary['bytes_per_frame']:.3f} | {fixed['skeletons']:,} | {fixed['bases']:,} | "
                                f"{fixed['meta']:,} | {fixed['priors']:,} | {fixed['container']:,} | "
                                f"{total / summary['output_bytes']:.0%} | {summary['output_bytes'] - total:,} | "
                                f"{seconds:.0f} |")
                    show(rows[-1])
        finally:
            by_name.POOL_FRAMES = default_pool
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--classes", default="pooled,subject,single,auto")
    parser.add_argument("--pool-frames", help="comma-separated thresholds: run `pooled` with each")
    parser.add_argument("--basis-precision", help="comma-separated basis precisions: run `pooled` with each")
    parser.add_argument("-e", "--error", type=float, default=1.0, help="target mean error, cm (default 1)")
    args = parser.parse_args(argv)
    default = Settings().basis_precision
    if args.pool_frames:
        runs = [("pooled", int(t), default) for t in args.pool_frames.split(",")]
    elif args.basis_precision:
        runs = [("pooled", by_name.POOL_FRAMES, float(p)) for p in args.basis_precision.split(",")]
    else:
        runs = [(classes, by_name.POOL_FRAMES, default) for classes in args.classes.split(",")]
    options = "".join(f" {flag} {value}" for flag, value in (("--pool-frames", args.pool_frames),
                      ("--basis-precision", args.basis_precision), ("-e", args.error if args.error != 1.0 else None))
                      if value)
    print(f"`python benchmarks/small_sets.py -j {args.jobs}{options}` ({os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.1f} at start).\n")
    run(runs, args.jobs, args.error, show=lambda row: print(row, flush=True))


if __name__ == "__main__":
    main()

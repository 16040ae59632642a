"""What bounding every joint costs: archive size against `--max-error`, per mean target.

    python benchmarks/max_error.py [DIR ...] [-j N] [--runs 1:none,1:10,...]

Compresses the folders (default: the shared CMU set, ../shared/data/cmu) once per (mean
target -e, --max-error) pair, "none" for no bound on a single joint, and prints one markdown
row per run: bytes per frame, the cost against the same -e without a bound, the clips' largest
mean, 99th percentile and max error (from the archive's rows), the frames patched and the
patch streams' share of the archive. The default of `--max-error` is chosen from this table
(docs/fidelity.md).
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from mocapzip.archive import Archive, Settings, compress  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
RUNS = "1:none,1:10,1:5,1:3,1:2,0.5:none,0.5:5,0.5:2,0.5:1"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", type=Path, default=[DATA])
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--runs", default=RUNS, help="comma-separated MEAN:MAX pairs (MAX 'none': no bound)")
    args = parser.parse_args(argv)
    print(f"`python benchmarks/max_error.py -j {args.jobs}` on {', '.join(p.name for p in args.inputs)} "
          f"({os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at start).\n")
    print("| -e (cm) | --max-error (cm) | bytes/frame | vs no bound | largest clip mean | largest clip p99 | "
          "max | frames patched | patch bytes | seconds |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    unbounded: dict[float, float] = {}
    for run in args.runs.split(","):
        mean_text, max_text = run.split(":")
        mean, bound = float(mean_text), None if max_text == "none" else float(max_text)
        with tempfile.TemporaryDirectory() as work:
            path = Path(work) / "set.mcz"
            started = time.perf_counter()
            summary = compress(args.inputs, path, Settings(error_cm=mean, max_error_cm=bound), jobs=args.jobs)
            seconds = time.perf_counter() - started
            with Archive(path) as archive:
                rows = archive.clips
                patch_bytes = sum(size for name, size in archive.stream_sizes().items() if name.startswith("patch/"))
        per_frame = summary["bytes_per_frame"]
        if bound is None:
            unbounded[mean] = per_frame
        cost = f"{per_frame / unbounded[mean] - 1:+.1%}" if mean in unbounded else "n/a"
        patched = sum(row.get("patched_frames", 0) for row in rows)
        print(f"| {mean:g} | {max_text} | {per_frame:.3f} | {cost} | {max(r['error_cm'] for r in rows):.3f} | "
              f"{max(r['p99_error_cm'] for r in rows):.2f} | {max(r['max_error_cm'] for r in rows):.2f} | "
              f"{patched:,} ({patched / summary['frames']:.1%}) | {patch_bytes:,} ({patch_bytes / summary['output_bytes']:.0%}) | "
              f"{seconds:.0f} |", flush=True)


if __name__ == "__main__":
    main()

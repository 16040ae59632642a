"""Issue 42's targets, measured in one run: the table in docs/fidelity.md ("Targets").

    python benchmarks/fidelity_targets.py [-j 2] [--acl-compressor PATH [--clips 20]]

On the shared CMU set (../shared/data/cmu) it compresses at `-e 1` with no bound on single
joints, with the default bound, with `--max-error` 5, 4 and 3, and at `-e 0.5 --max-error 1`, and
reads each archive's size; on the Bandai BVH set at `-e 1` it measures the clip edges
(`clip_edges.edge_errors`). With `--acl-compressor` (ACL built as benchmarks/acl.py says) it
also runs benchmarks/acl.py at 24 and 120 fps and takes its line "mcz at ACL's worst vertex
error ...". Prints one markdown row per target: what the issue measured before (a0c827c), this
run, the target, and whether it is met.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import re  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import mocapzip  # noqa: E402
from mocapzip.defaults import MAX_TO_MEAN  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from clip_edges import edge_errors  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
BOUNDS = (5.0, 4.0, 3.0)  # candidate default bounds at -e 1, besides the default
DEFAULT_BUDGET = 0.15  # the issue: the default bound is the tightest that costs at most 15 % over the mean alone
# benchmarks/acl.py's -e:MAX:VERTEX runs: every vertex held to ACL's own worst ("acl"), with the default
# representation ("auto": `channels` at such errors, docs/fidelity.md), at two mean targets; -e 1 as the loose
# end its interpolation needs
ACL_RUNS = "1:10,0.004:none:acl,0.009:none:acl"


def bytes_per_frame(inputs: Path, jobs: int, **options) -> float:
    with tempfile.TemporaryDirectory() as scratch, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        summary = mocapzip.compress(inputs, Path(scratch) / "x.mcz", jobs=jobs, **options)
    return summary["bytes_per_frame"]


def acl_ratio(compressor: Path, fps: int, clips: int, jobs: int) -> str:
    """benchmarks/acl.py's "mcz at ACL's worst vertex error" ratio at `fps`, or what it said instead."""
    command = [sys.executable, str(Path(__file__).with_name("acl.py")), "--acl-compressor", str(compressor),
               "--fps", str(fps), "--clips", str(clips), "--runs", ACL_RUNS, "-j", str(jobs)]
    output = subprocess.run(command, capture_output=True, text=True, check=True).stdout
    said = re.search(r"mcz at ACL's worst vertex error with defaults[^:]*\): (.*)\.$", output, re.M)
    return said.group(1) if said else "no result"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--acl-compressor", type=Path, help="ACL's tools/acl_compressor, built (benchmarks/acl.py)")
    parser.add_argument("--clips", type=int, default=20, help="clips for the ACL runs (default 20)")
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    cmu, bandai = DATA / "cmu", DATA / "bvh-bandai"
    mean_only = bytes_per_frame(cmu, args.jobs, error=1.0, max_error=None)
    default = bytes_per_frame(cmu, args.jobs, error=1.0)
    bounded = {bound: bytes_per_frame(cmu, args.jobs, error=1.0, max_error=bound) for bound in BOUNDS}
    tight = bytes_per_frame(cmu, args.jobs, error=0.5, max_error=1.0)
    affordable = [b for b, size in bounded.items() if size <= (1 + DEFAULT_BUDGET) * mean_only]
    with tempfile.TemporaryDirectory() as scratch, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        archive = Path(scratch) / "bandai.mcz"
        mocapzip.compress(bandai, archive, error=1.0, jobs=args.jobs)
        edges = edge_errors(archive, bandai)
    acl = {fps: acl_ratio(args.acl_compressor, fps, args.clips, args.jobs) if args.acl_compressor else "not run"
           for fps in (120, 24)}
    print(f"`python benchmarks/fidelity_targets.py {' '.join(sys.argv[1:] if argv is None else argv)}`: "
          f"{os.cpu_count()} CPUs, load average {load:.1f} at start, {os.getloadavg()[0]:.1f} at end.\n")
    print("| measure | before (a0c827c) | this run | target |")
    print("|---|---:|---:|---:|")
    print(f"| bytes at ACL's worst vertex error (its defaults, same clips), 120 fps | 1.22× ACL | {acl[120]} | ≤ 0.7× ACL |")
    print(f"| the same at 24 fps | not reachable (1.43× at the nearest) | {acl[24]} | ≤ 0.8× ACL |")
    print(f"| `-e 1 --max-error 3` against `-e 1` alone | 2.25× | {bounded[3.0] / mean_only:.2f}× | ≤ 1.3× |")
    print(f"| `-e 0.5 --max-error 1` | 11.2 B/frame | {tight:.2f} B/frame | ≤ 5 B/frame |")
    print(f"| first and last 2 frames' mean error / the clip's (median; Bandai, `-e 1`) | 1.5–1.7× | "
          f"{edges['edge']:.2f}× ({edges['at_edge']} of {edges['clips']} clips' worst joint there) | ≤ 1.1× |")
    print(f"| default worst-joint bound | 10 × `-e` | {MAX_TO_MEAN:g} × `-e` ({default / mean_only - 1:+.1%}); "
          f"the tightest within +{DEFAULT_BUDGET:.0%}: "
          f"{f'{min(affordable):g} cm' if affordable else 'none of ' + ', '.join(f'{b:g}' for b in BOUNDS)} "
          f"({', '.join(f'{b:g} cm {size / mean_only - 1:+.0%}' for b, size in bounded.items())}) | ≤ 3 × `-e`, ≤ +15 % |")
    print(f"| the mean-target mode at 1 cm (`-e 1 --max-error none`) | 1.643 B/frame (3109368) | {mean_only:.3f} "
          f"B/frame ({mean_only / 1.643 - 1:+.1%}); with the default bound {default:.3f} | no worse than +1 % |")


if __name__ == "__main__":
    main()

"""Where the worst joints are: each joint's error spread at a mean target, and the frames beyond a bound.

    python benchmarks/joint_spread.py [--data cmu|bandai|DIR] [-e 1] [--beyond 3] [-t dct-edges] [-j 2]

Compresses the set at `-e` with no bound on single joints (`--max-error none`), decodes every clip
through the API and measures each joint of each frame against the source. Prints the archive's
bytes, how many frames have a joint beyond `--beyond` cm and in how many runs of consecutive
frames, and per joint its mean, 99th percentile and largest error over every clip. This is what
a bound on every joint must patch (docs/fidelity.md "Targets"): a bound near each joint's own
99th percentile patches ordinary frames, not rare events.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import mocapzip  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from clip_edges import SETS, joint_errors  # noqa: E402


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default="cmu", help="cmu, bandai or a folder of clips")
    parser.add_argument("-e", "--error", type=float, default=1.0)
    parser.add_argument("--beyond", type=float, default=3.0, help="count the frames with a joint beyond this, cm")
    parser.add_argument("-t", "--transform", default="dct-edges")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    folder = SETS.get(args.data, Path(args.data))
    load = os.getloadavg()[0]
    per_joint: dict[str, list[np.ndarray]] = {}
    frames = beyond = runs = 0
    run_lengths = []
    with tempfile.TemporaryDirectory() as scratch, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the glitches and cut-short frames compress reports
        archive = Path(scratch) / "x.mcz"
        summary = mocapzip.compress(folder, archive, error=args.error, max_error=None,
                                    transform={"id": args.transform}, jobs=args.jobs)
        for clip, errors in joint_errors(archive, folder):
            for j, name in enumerate(clip.joint_names):
                per_joint.setdefault(name, []).append(errors[:, j])
            over = np.any(errors > args.beyond, axis=1)
            frames, beyond = frames + len(over), beyond + int(over.sum())
            edges = np.diff(np.r_[0, over.astype(np.int8), 0])
            lengths = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
            runs += len(lengths)
            run_lengths.extend(lengths.tolist())
    print(f"`python benchmarks/joint_spread.py {' '.join(sys.argv[1:] if argv is None else argv)}`: {folder.name}, "
          f"-e {args.error:g} --max-error none -t {args.transform}, {summary['output_bytes']:,} bytes; "
          f"{os.cpu_count()} CPUs, load average {load:.1f} at start, {os.getloadavg()[0]:.1f} at end.\n")
    median_run = float(np.median(run_lengths)) if run_lengths else 0.0
    print(f"Frames with a joint beyond {args.beyond:g} cm: {beyond:,} of {frames:,} ({beyond / frames:.1%}), "
          f"in {runs:,} runs of a median {median_run:g} frames.\n")
    print("| joint | mean (cm) | p99 (cm) | p99 / mean | max (cm) |")
    print("|---|---:|---:|---:|---:|")
    spread = {name: np.concatenate(parts) for name, parts in per_joint.items()}
    for name, errors in sorted(spread.items(), key=lambda item: -item[1].mean()):
        mean, p99 = errors.mean(), np.percentile(errors, 99)
        print(f"| {name} | {mean:.2f} | {p99:.2f} | {p99 / mean:.1f} | {errors.max():.1f} |")


if __name__ == "__main__":
    main()

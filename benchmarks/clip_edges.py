"""Clip edges: how much worse a clip's first and last frames come back than the rest.

    python benchmarks/clip_edges.py [--data bandai|cmu|DIR] [-e 1] [-t dct-edges -t dct-edges:4 -t dct] [-j 2]

Compresses the set once per transform (`-t`, at `-e`), decodes every clip through the API and
measures each frame's mean joint error against the source. Per transform: the archive's bytes,
the median over clips of (the first and last 2 frames' mean error / the clip's mean error), the
clips whose worst joint is in those frames, and the median of the first and of the last frame
alone. Game engines join clips at these frames (loops, blends), so they should be no worse
than the middle: issue 42's target is 1.1x at most (docs/fidelity.md "Clip edges").
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

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SETS = {"bandai": DATA / "bvh-bandai", "cmu": DATA / "cmu"}
EDGE = 2  # frames at each end


def joint_errors(archive: Path, folder: Path):
    """Yield (clip, (frames, joints) cm) for each clip of `archive`, compressed from `folder`: each
    joint of each frame, decoded through the API, against the source's."""
    with mocapzip.open(archive) as opened, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a source cut short mid-frame: dropped, as compress did
        for path in opened.paths:
            clip = opened[path]
            if clip.format == "bvh":
                original = mocapzip.bvh_joint_positions(mocapzip.read_bvh(folder / path))
            else:
                original = mocapzip.joint_positions(clip.skeleton, mocapzip.read_amc(folder / path, clip.skeleton))
            yield clip, np.linalg.norm(clip.positions() - original, axis=-1)


def edge_errors(archive: Path, folder: Path) -> dict:
    """Per clip of `archive` (compressed from `folder`): its edge ratio, whether its worst joint is at an
    edge, and its first and last frames' mean error against the clip's."""
    ratios, at_edge, first, last = [], 0, [], []
    for _, distances in joint_errors(archive, folder):
        per_frame = distances.mean(axis=1)
        mean = per_frame.mean()
        ratios.append(np.r_[per_frame[:EDGE], per_frame[-EDGE:]].mean() / mean)
        first.append(per_frame[0] / mean)
        last.append(per_frame[-1] / mean)
        worst = np.unravel_index(distances.argmax(), distances.shape)[0]
        at_edge += worst < EDGE or worst >= len(per_frame) - EDGE
    return {"clips": len(ratios), "edge": float(np.median(ratios)), "at_edge": at_edge,
            "first": float(np.median(first)), "last": float(np.median(last))}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default="bandai", help="bandai, cmu or a folder of clips")
    parser.add_argument("-e", "--error", type=float, default=1.0)
    parser.add_argument("-t", "--transform", action="append",
                        help="transforms to compare (default dct-edges, dct); dct-edges:N codes N columns by their ends")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    folder = SETS.get(args.data, Path(args.data))
    transforms = args.transform or ["dct-edges", "dct"]
    load = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for transform in transforms:
            archive = Path(scratch) / f"{transform.replace(':', '-')}.mcz"
            name, _, columns = transform.partition(":")
            config = {"id": name, **({"edge_columns": int(columns)} if columns else {})}
            summary = mocapzip.compress(folder, archive, error=args.error, transform=config, jobs=args.jobs)
            rows.append((transform, summary["output_bytes"], edge_errors(archive, folder)))
    base = rows[-1][1]
    print(f"`python benchmarks/clip_edges.py {' '.join(sys.argv[1:] if argv is None else argv)}`: {folder.name}, "
          f"-e {args.error:g}; {os.cpu_count()} CPUs, load average {load:.1f} at start, {os.getloadavg()[0]:.1f} at end.\n")
    print(f"| transform | bytes | vs {rows[-1][0]} | first and last {EDGE} frames / clip mean (median) | "
          f"first frame | last frame | clips whose worst joint is there |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for transform, size, e in rows:
        print(f"| {transform} | {size:,} | {size / base - 1:+.1%} | {e['edge']:.2f} | {e['first']:.2f} | {e['last']:.2f} | "
              f"{e['at_edge']} of {e['clips']} |")


if __name__ == "__main__":
    main()

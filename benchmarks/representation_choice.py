"""`-r aligned` against `-r channels` across -e: the measure behind compress's default
representation, "auto" (`archive.settings.chosen_representation`; docs/fidelity.md,
"Representation by error").

    python benchmarks/representation_choice.py [--fps 24] [--clips 20] [--bound none|default|vertex:K]
        [-e 0.2,0.1,0.07,0.05,0.03,0.02] [-j 2]

The clips are benchmarks/acl.py's (`--clips` spread over the shared CMU set, every 120/fps-th
frame written as ASF/AMC); each is compressed with both representations at every -e, with no
joint bound (`none`), the default one (5 x -e) or every vertex within K x -e and no joint bound
(`vertex:K`). Prints a markdown table of the archives' bytes and what "auto" picks.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES, DEFAULT_FPS  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import mocapzip  # noqa: E402
from mocapzip.archive.settings import Settings, chosen_representation  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from acl import SETS, pick, write_inputs  # noqa: E402


def bounds(text: str, error_cm: float) -> dict:
    """compress's keywords for `--bound` at `error_cm`."""
    if text == "none":
        return {"max_error": None}
    if text == "default":
        return {}
    kind, _, factor = text.partition(":")
    if kind != "vertex" or not factor:
        sys.exit(f"--bound must be none, default or vertex:K, not {text!r}")
    return {"max_error": None, "max_vertex_error": float(factor) * error_cm}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fps", type=int, default=24, help="a divisor of 120 (default 24)")
    parser.add_argument("--clips", type=int, default=20)
    parser.add_argument("--bound", default="none", help="none, default (5 x -e) or vertex:K (K x -e)")
    parser.add_argument("-e", "--errors", default="0.2,0.1,0.07,0.05,0.03,0.02")
    parser.add_argument("-j", "--jobs", type=int, default=1)
    args = parser.parse_args(argv)
    if args.fps < 1 or DEFAULT_FPS % args.fps:
        parser.error(f"--fps {args.fps} does not divide {DEFAULT_FPS:g}")
    load = os.getloadavg()[0]
    rows = ["| -e (cm) | aligned bytes | channels bytes | channels / aligned | auto picks |", "|---:|---:|---:|---:|---|"]
    with tempfile.TemporaryDirectory() as scratch:
        clips = Path(scratch) / "clips"
        write_inputs(pick(SETS["cmu"], args.clips), SETS["cmu"], int(DEFAULT_FPS) // args.fps, clips)
        for error in (float(e) for e in args.errors.split(",")):
            sizes = {}
            for name in ("aligned", "channels"):
                summary = mocapzip.compress(clips, Path(scratch) / "set.mcz", error=error, jobs=args.jobs, force=True,
                                            progress=False, fps=args.fps, representation=name,
                                            **bounds(args.bound, error))
                sizes[name] = summary["output_bytes"]
            given = bounds(args.bound, error).get("max_vertex_error")
            auto = chosen_representation(Settings(error_cm=error, vertex_error_cm=given, fps=args.fps))
            rows.append(f"| {error:g} | {sizes['aligned']:,} | {sizes['channels']:,} | "
                        f"{sizes['channels'] / sizes['aligned']:.3f} | {auto} |")
    print(f"`python benchmarks/representation_choice.py {' '.join(sys.argv[1:] if argv is None else argv)}`: "
          f"{args.clips} CMU clips at {args.fps} fps; {os.cpu_count()} CPUs, load average {load:.1f} at start, "
          f"{os.getloadavg()[0]:.1f} at end.\n")
    print("\n".join(rows))


if __name__ == "__main__":
    main()

"""`mcz compress --dask` on this machine, and what a larger cluster would take (docs/cluster.md).

    python benchmarks/cluster.py [--data ../shared/data] [--repeat 3]

1. Scaling. The shared CMU set at the defaults (1 cm), compressed with -j 1, -j 2, --dask local:1
   and --dask local:2: the median wall time of `--repeat` runs each, run in turn (one of each,
   then again), every archive checked byte-identical to the first.
2. Tasks. One --dask local:2 run inside this process with Dask's task stream on: per kind of task
   (the function it maps) its count, its compute time and the bytes of its results; per map, its
   tasks' compute times.
3. Estimate, on paper, for N workers and a library of LIBRARY_FRAMES frames taken as C copies of
   the shared set (the same mix of classes and clips, so C times as many classes and clips). On
   a cluster the run has three maps (read each clip, code each class, re-code each clip with the
   priors), each ending before the next starts. A map of tasks t_1..t_k, C times over, takes at
   least max(max t_i, C sum t_i / N) on N workers, and is taken as that bound. The client's own
   work (the CPU time of this process during the run: taking each clip in, summing covariances,
   training the priors, writing) runs on one core, C times over, whatever N. Much of it overlaps
   the maps (the client takes clips in while the workers read others), so the run takes between
   the larger of the two and their sum; both are given. The cluster's start is counted once.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
MCZ = Path(sys.executable).with_name("mcz")
RUNS = (("-j 1", ["-j", "1"]), ("-j 2", ["-j", "2"]), ("--dask local:1", ["--dask", "local:1"]),
        ("--dask local:2", ["--dask", "local:2"]))
LIBRARY_FRAMES = 40_000_000
WORKER_COUNTS = (1, 2, 10, 100)


def scaling(data: Path, repeat: int, folder: Path) -> dict[str, float]:
    """Median wall seconds of each run; every archive byte-identical to the first."""
    times = defaultdict(list)
    first = None
    for _ in range(repeat):
        for name, args in RUNS:
            out = folder / "run.mcz"
            started = time.perf_counter()
            subprocess.run([MCZ, "compress", data / "cmu", "-o", out, "-f", "-q", *args], check=True,
                           stderr=subprocess.DEVNULL)
            times[name].append(time.perf_counter() - started)
            archive = out.read_bytes()
            first = first or archive
            if archive != first:
                sys.exit(f"{name}: the archive differs from the first run's")
    return {name: statistics.median(t) for name, t in times.items()}


def task_stream(data: Path, folder: Path) -> tuple[float, float, float, int, list[dict]]:
    """(cluster start seconds, compress wall seconds, this process's CPU seconds in it, frames, Dask's
    task records) of one --dask local:2 run."""
    import distributed

    from mocapzip import archive
    from mocapzip.cluster import on_cluster
    from mocapzip.archive.settings import DEFAULT_ERROR_CM
    from mocapzip.defaults import MAX_TO_MEAN

    started = time.perf_counter()
    with on_cluster("local:2") as run:
        ready = time.perf_counter() - started
        with distributed.get_task_stream(run.client) as stream:
            started, cpu = time.perf_counter(), time.process_time()
            settings = archive.Settings(max_error_cm=MAX_TO_MEAN * DEFAULT_ERROR_CM)  # as `mcz compress`
            summary = archive.compress([os.fspath(data / "cmu")], folder / "stream.mcz", settings,
                                       force=True, jobs=run.workers)
            if (folder / "stream.mcz").read_bytes() != (folder / "run.mcz").read_bytes():
                sys.exit("the task stream's run wrote another archive than the command's")
            wall, cpu = time.perf_counter() - started, time.process_time() - cpu
    return ready, wall, cpu, summary["frames"], stream.data


def maps_of(records: list[dict]) -> dict[str, list[tuple[str, float, int]]]:
    """Task records by map (the key's state id): (function, compute seconds) per task."""
    maps = defaultdict(list)
    for record in records:
        function, state_id, _ = str(record["key"]).rsplit("-", 2)
        compute = sum(s["stop"] - s["start"] for s in record["startstops"] if s["action"] == "compute")
        maps[state_id].append((function, compute))
    return maps


def map_seconds(tasks: list[float], workers: int, copies: float = 1.0) -> float:
    return max(max(tasks), copies * sum(tasks) / workers)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--repeat", type=int, default=3)
    options = parser.parse_args()
    with open("/proc/loadavg") as file:
        load = file.read().split()[0]
    print(f"{os.cpu_count()} CPUs; load average {load} at start\n")
    with tempfile.TemporaryDirectory() as folder:
        medians = scaling(options.data, options.repeat, Path(folder))
        ready, wall, client, frames, records = task_stream(options.data, Path(folder))
    base = medians["-j 1"]
    print(f"#### Scaling: shared CMU set, 1 cm, median of {options.repeat} runs (archives byte-identical)\n")
    print("| run | seconds | x -j 1 |\n|---|---:|---:|")
    for name, seconds in medians.items():
        print(f"| {name} | {seconds:.2f} | {base / seconds:.2f} |")

    maps = maps_of(records)
    print(f"\n#### Tasks of one --dask local:2 run ({wall:.2f} s; the cluster started in {ready:.2f} s)\n")
    print("| task | maps | count | compute s | mean ms | longest ms |\n|---|---:|---:|---:|---:|---:|")
    kinds = defaultdict(list)
    for state_id, tasks in maps.items():
        for function, compute in tasks:
            kinds[function].append((state_id, compute))
    for function, rows in kinds.items():
        computes = [c for _, c in rows]
        print(f"| {function} | {len({m for m, _ in rows})} | {len(rows)} | {sum(computes):.2f} | "
              f"{1e3 * statistics.mean(computes):.1f} | {1e3 * max(computes):.1f} |")

    copies = LIBRARY_FRAMES / frames
    bounds = sum(map_seconds([c for _, c in tasks], 2) for tasks in maps.values())
    print(f"\n{len(maps)} maps, whose bounds at 2 workers sum to {bounds:.2f} s; the client's CPU time in the "
          f"run: {client:.2f} s.\n")
    print(f"#### Estimate: {LIBRARY_FRAMES / 1e6:.0f} M frames ({copies:.0f} copies of the set's "
          f"{frames:,} frames)\n")
    print("| workers | maps s | client s | hours, overlapped | hours, one after the other | frames/s |\n"
          "|---:|---:|---:|---:|---:|---:|")
    for n in WORKER_COUNTS:
        in_maps = sum(map_seconds([c for _, c in tasks], n, copies) for tasks in maps.values())
        low, high = max(in_maps, copies * client) + ready, in_maps + copies * client + ready
        print(f"| {n} | {in_maps:,.0f} | {copies * client:,.0f} | {low / 3600:.2f} | {high / 3600:.2f} | "
              f"{LIBRARY_FRAMES / high:,.0f} to {LIBRARY_FRAMES / low:,.0f} |")


if __name__ == "__main__":
    main()

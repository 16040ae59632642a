"""Compress and decompress speed of mcz beside xz and zstd, on the same files in the same run.

    python benchmarks/speed.py [--data ../shared/data] [--set cmu] [--json speed.json]

mcz compresses the folder `$DATA/SET` (every clip within 1 cm) into one archive and decompresses
it back to ASF/AMC files, each with `-j 1` and `-j 2`; the first `-j 1` run starts with an empty
compiled-code cache (`NUMBA_CACHE_DIR` in a new folder: the cold start a fresh install pays once),
the others reuse it (warm; decompress runs once untimed first, for the kernels only it uses). xz -9, xz -d, zstd -19 and zstd -3 compress and decompress the same
files, packed into one uncompressed tar first (not timed), single-threaded as their defaults.
Every run is a child process: its time is wall time including interpreter start-up, its memory
the child's peak RSS (GNU time, /usr/bin/time). A run under 5 s is made 5 times and the median
kept. mcz's runs write Python's bytecode cache, as an installed package has it, even where
PYTHONDONTWRITEBYTECODE is set (`_writing_bytecode`). Speeds are frames/s and MB/s of AMC text (ASF text included in
the bytes), and ratios against xz -9 (or xz -d) measured in this run. The load average is
recorded before and after: other work on the machine slows every row alike, not the ratios.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tarfile
import tempfile
from pathlib import Path

from mocapzip.bench.runner import run_measured

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
TIME = "/usr/bin/time"  # GNU time (Debian package `time`): the children's peak RSS


def mcz(*args: str) -> list[str]:
    return [sys.executable, "-c", "from mocapzip.cli.main import main; main()", *args]


QUICK_SECONDS = 5.0  # a run shorter than this is made REPEATS times, and the median time kept
REPEATS = 5


def measured(name: str, argv: list[str], env: dict | None = None, stdin: Path | None = None,
             stdout: Path | None = None, log=print, before=lambda: None) -> dict:
    """Run one command (stdin/stdout redirected to files when given; `before` each run): its wall
    seconds and peak RSS. A run under QUICK_SECONDS is made REPEATS times and the median time kept
    (and the largest peak): the shared CMU set decompresses in about 2 s, and one such run moved by
    10-15 % with the machine's other load, more than the changes it was measuring."""
    runs = []
    while not runs or (runs[0]["seconds"] < QUICK_SECONDS and len(runs) < REPEATS):
        before()
        runs.append(_measured_once(name, argv, env, stdin, stdout, log))
    seconds = sorted(run["seconds"] for run in runs)[len(runs) // 2]
    if len(runs) > 1:
        log(f"{name}: median {seconds:.2f} s of {len(runs)} runs")
    return {"name": name, "seconds": seconds, "runs": len(runs), "peak_rss_mb": max(run["peak_rss_mb"] for run in runs)}


def _measured_once(name: str, argv: list[str], env: dict | None, stdin: Path | None, stdout: Path | None,
                   log) -> dict:
    """One run of `measured`. The peak RSS comes from GNU time run in between: a child forked
    straight from this (large) Python process would report this process's size as its own peak
    (Linux keeps the high-water mark across exec), which hides the small baselines' real memory."""
    with tempfile.NamedTemporaryFile("r") as rss:
        argv = [TIME, "-f", "%M", "-o", rss.name, *argv]
        if stdin is not None or stdout is not None:
            argv = ["sh", "-c", " ".join(f"'{a}'" for a in argv) + (f" < '{stdin}'" if stdin else "")
                    + (f" > '{stdout}'" if stdout else "")]
        result = run_measured(argv, env=env, echo=log)
        if result["returncode"] != 0:
            raise SystemExit(f"{name}: exit {result['returncode']}: {' '.join(result['stderr'][-3:])}")
        peak_mb = int(rss.read().split()[-1]) / 1024
    log(f"{name}: {result['seconds']:.2f} s, peak RSS {peak_mb:.0f} MB")
    return {"name": name, "seconds": result["seconds"], "peak_rss_mb": peak_mb}


def _writing_bytecode(environment) -> dict:
    """`environment` without PYTHONDONTWRITEBYTECODE: mcz's runs keep Python's compiled bytecode
    (__pycache__), as an installed package has it. Where that variable was set (it was where this
    page was first made), every run compiled mcz's 64 modules from source: 0.08 s of a 1.6 s
    decompress of the shared CMU set."""
    return {name: value for name, value in environment.items() if name != "PYTHONDONTWRITEBYTECODE"}


def run(data: Path, subset: str, log=print) -> dict:
    from mocapzip.archive import info
    from mocapzip.inputs.discover import find_clips

    folder = data / subset
    sources = find_clips([folder])
    files = sorted({s.motion for s in sources} | {s.skeleton for s in sources})
    megabytes = sum(f.stat().st_size for f in files) / 1e6
    load_start = os.getloadavg()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        archive = tmp / "set.mcz"
        cache = tmp / "numba-cache"
        env = {**_writing_bytecode(os.environ), "NUMBA_CACHE_DIR": str(cache)}
        for label, jobs, cold in (("mcz compress -j 1, cold start", 1, True), ("mcz compress -j 1", 1, False),
                                  ("mcz compress -j 2", 2, False)):
            argv = mcz("compress", str(folder), "-o", str(archive), "-f", "-q", "-j", str(jobs))
            empty_cache = (lambda: shutil.rmtree(cache, ignore_errors=True)) if cold else (lambda: None)
            rows.append(measured(label, argv, env, log=log, before=empty_cache))  # each cold run starts empty
        frames, archive_bytes = info(archive)["frames"], archive.stat().st_size
        out = tmp / "out"  # compress does not use the AMC writer's kernels: compile them first, untimed
        run_measured(mcz("decompress", str(archive), "-o", str(out), "-q", "-j", "1"), env=env, echo=log)
        for label, jobs in (("mcz decompress -j 1", 1), ("mcz decompress -j 2", 2)):
            rows.append(measured(label, mcz("decompress", str(archive), "-o", str(out), "-q", "-j", str(jobs)), env,
                                 log=log, before=lambda: shutil.rmtree(out, ignore_errors=True)))

        packed = tmp / "set.tar"
        with tarfile.open(packed, "w") as tar:
            for f in files:
                tar.add(f, arcname=str(f.relative_to(folder)))
        sizes = {"mcz -e 1": archive_bytes}
        for name, compress, decompress in (("xz -9", ["xz", "-9", "-T1", "-c"], ["xz", "-d", "-T1", "-c"]),
                                           ("zstd -19", ["zstd", "-19", "-q", "-c"], ["zstd", "-d", "-q", "-c"]),
                                           ("zstd -3", ["zstd", "-3", "-q", "-c"], ["zstd", "-d", "-q", "-c"])):
            squeezed = tmp / "set.tar.x"
            rows.append(measured(name, compress, stdin=packed, stdout=squeezed, log=log))
            sizes[name] = squeezed.stat().st_size
            rows.append(measured(f"{name} decompress", decompress, stdin=squeezed, stdout=tmp / "set.back", log=log))
    times = {row["name"]: row["seconds"] for row in rows}
    for row in rows:
        row["frames_per_second"] = frames / row["seconds"]
        row["mb_per_second"] = megabytes / row["seconds"]
        row["vs_xz"] = times["xz -9 decompress" if "decompress" in row["name"] else "xz -9"] / row["seconds"]
    return {"set": f"$DATA/{subset}", "clips": len(sources), "frames": frames, "megabytes": megabytes,
            "bytes": sizes, "rows": rows, "cpus": os.cpu_count(),
            "load_average_start": load_start, "load_average_end": os.getloadavg()}


def markdown(report: dict) -> str:
    lines = [f"`python benchmarks/speed.py` on {report['set']} ({report['clips']} clips, {report['frames']:,} frames, "
             f"{report['megabytes']:.1f} MB of ASF/AMC text; {report['cpus']} CPUs, load average "
             f"{report['load_average_start'][0]:.1f} at start, {report['load_average_end'][0]:.1f} at end). Times are "
             "wall times of child processes, interpreter start-up included; a run under "
             f"{QUICK_SECONDS:.0f} s is the median of {REPEATS}. x xz is xz -9's time (xz -d's for "
             "decompression) over this row's, measured in the same run.", "",
             "| run | seconds | frames/s | MB/s | x xz | peak RSS (MB) |", "|---|---:|---:|---:|---:|---:|"]
    for row in report["rows"]:
        lines.append(f"| {row['name']} | {row['seconds']:.2f} | {row['frames_per_second']:,.0f} | "
                     f"{row['mb_per_second']:.1f} | {row['vs_xz']:.2f} | {row['peak_rss_mb']:.0f} |")
    sizes = ", ".join(f"{name} {size:,} B" for name, size in report["bytes"].items())
    lines += ["", f"Sizes: {sizes}."]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--set", default="cmu", help="folder under --data to compress (default: cmu)")
    parser.add_argument("--json", type=Path, help="also write the report as JSON here")
    args = parser.parse_args(argv)
    report = run(args.data, args.set, log=lambda m: print(m, file=sys.stderr, flush=True))
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    print(markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())

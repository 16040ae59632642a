"""Speed and peak memory of mcz, xz -9, zstd -19 and Hou et al. on the largest shared clips and the whole CMU set.

    python benchmarks/speed_memory.py [--data ../shared/data] [--out DIR] [--whole cmu.json]

* The three largest shared CMU clips: one `mcz bench` run (mcz at 1 cm and every baseline).
* The whole shared CMU set: the report of `ratio_distortion.py` (`--whole`), or a new run.
* mcz compress of one subject folder with mcz's default of one BLAS thread per process and with
  as many BLAS threads as CPUs, to show what BLAS oversubscription costs on a busy machine.
* Bounded memory: mcz compress of the whole shared CMU set with the default clip cache and with
  none (`--cache-mb 0`), and of the set twice over (every subject folder linked under two names)
  with none: peak memory follows the cache, not the size of the database.

Every encode and decode of mcz, xz and zstd runs in its own child process: its peak memory is
that process's `ru_maxrss` (wait4), its time excludes interpreter start-up. Hou et al. run in
the bench process itself (no peak memory of their own).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

from mocapzip.defaults import BLAS_THREAD_VARIABLES, DEFAULT_CACHE_MB

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"


def largest_clips(data: Path, count: int = 3) -> list[str]:
    lines = (data / "MANIFEST.tsv").read_text(encoding="utf-8").splitlines()
    header = lines[0].split("\t")
    f, n = header.index("file"), header.index("frames")
    rows = [line.split("\t") for line in lines[1:]]
    amc = [(int(r[n]), r[f]) for r in rows if r[f].startswith("cmu/") and r[f].lower().endswith(".amc")]
    return [p for _, p in sorted(amc, reverse=True)[:count]]


def blas_threads(data: Path, log=print) -> dict:
    """`mcz compress cmu/07` with mcz's default (one BLAS thread per process) and one per CPU."""
    from mocapzip.bench.runner import run_measured

    out = {}
    cpus = str(os.cpu_count() or 1)
    with tempfile.TemporaryDirectory() as tmp:
        for name, value in (("one thread", None), ("one per CPU", cpus)):
            env = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
            if value:
                env.update({k: value for k in BLAS_THREAD_VARIABLES})
            argv = [sys.executable, "-c", "from mocapzip.cli.main import main; main()", "compress",
                    str(data / "cmu" / "07"), "-o", str(Path(tmp) / f"{name[-3:]}.mcz"), "-q"]
            log(f"$ {f'OPENBLAS_NUM_THREADS={value} ' if value else ''}mcz compress $DATA/cmu/07 -o x.mcz -q")
            result = run_measured(argv, env=env, echo=log)
            out[name] = result
            log(f"  {result['seconds']:.1f} s wall, peak RSS {result['peak_rss_mb']:.0f} MB")
    return out


def bounded_memory(data: Path, jobs: int, log=print, quick: bool = False) -> dict:
    """Peak RSS and time of `mcz compress` on the CMU set (one subject folder if `quick`) with the
    default clip cache and with none, and on the set twice over with none."""
    from mocapzip.archive import info
    from mocapzip.bench.runner import run_measured

    source = data / "cmu" / "07" if quick else data / "cmu"
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        twice = Path(tmp) / "twice"
        for copy in ("a", "b"):  # real folders of linked files: input discovery does not follow linked folders
            for file in (f for f in source.rglob("*") if f.is_file()):
                link = twice / copy / file.relative_to(source)
                link.parent.mkdir(parents=True, exist_ok=True)
                link.symlink_to(file)
        label = f"$DATA/{source.relative_to(data)}"
        runs = (("default cache", source, label, []), ("no cache", source, label, ["--cache-mb", "0"]),
                ("no cache, set twice", twice, f"TWICE ({label} as a/ and b/)", ["--cache-mb", "0"]))
        for name, folder, label, options in runs:
            archive = Path(tmp) / "x.mcz"
            argv = [sys.executable, "-c", "from mocapzip.cli.main import main; main()", "compress", str(folder),
                    "-o", str(archive), "-f", "-q", "-j", str(jobs), *options]
            log(f"$ mcz compress {label} -o x.mcz -f -q -j {jobs} {' '.join(options)}")
            result = run_measured(argv, echo=log)
            out[name] = {**result, "frames": info(archive)["frames"]}
            log(f"  {out[name]['frames']:,} frames, {result['seconds']:.1f} s wall, "
                f"peak RSS {result['peak_rss_mb']:.0f} MB")
    return {"jobs": jobs, "runs": out}


def run(data: Path = DATA, out: Path = Path("."), whole: dict | None = None, jobs: int = 2, log=print,
        quick: bool = False) -> dict:
    sys.path.insert(0, str(Path(__file__).parent))
    from ratio_distortion import bench_run

    out.mkdir(parents=True, exist_ok=True)
    clips = largest_clips(data, 1 if quick else 3)
    largest = bench_run([*(str(data / c) for c in clips), "-e", "1", "-j", str(jobs), "-q"], out / "largest.json", log)
    if whole is None:
        whole = bench_run([str(data / "cmu"), "-e", "1", "-e", "0.5", "-j", str(jobs), "-q"], out / "cmu.json", log)
    return {"largest": largest, "whole": whole, "blas": blas_threads(data, log), "largest_clips": clips,
            "memory": bounded_memory(data, jobs, log, quick)}


def _rows(report: dict) -> list[str]:
    xz = next((r for r in report["runs"] if r["codec"] == "xz"), None)
    rows = []
    for run in report["runs"]:
        o = run["overall"]
        if not o:
            continue
        name = {"mcz": f"mcz {run['target_error_cm']:g} cm", "hou": f"Hou et al. per clip {run['target_error_cm']:g} cm",
                "hou-shared": f"Hou et al. basis per subject {run['target_error_cm']:g} cm",
                "xz": "xz -9", "zstd": "zstd -19"}[run["codec"]]
        enc_vs = o["encode_fps"] / xz["overall"]["encode_fps"] if xz else float("nan")
        dec_vs = o["decode_fps"] / xz["overall"]["decode_fps"] if xz else float("nan")
        rss = (f"{o['encode_peak_rss_mb']:.0f} | {o['decode_peak_rss_mb']:.0f}"
               if o.get("encode_peak_rss_mb") else "(in bench process) | (in bench process)")
        rows.append(f"| {name} | {o['frames']:,} | {o['encode_seconds']:.1f} | {o['encode_fps']:,.0f} | {enc_vs:.2f} | "
                    f"{o['decode_seconds']:.2f} | {o['decode_fps']:,.0f} | {dec_vs:.2f} | {rss} | {o['bytes_per_frame']:.2f} |")
    return rows


def markdown(results: dict) -> str:
    out = []
    head = ("| codec | frames | encode s | encode frames/s | x xz -9 | decode s | decode frames/s | x xz -9 "
            "| encode peak RSS (MB) | decode peak RSS (MB) | bytes/frame |")
    sep = "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    for key, title in (("largest", "Largest shared clips: " + ", ".join(Path(c).stem for c in results["largest_clips"])),
                       ("whole", "Whole shared CMU set")):
        report = results[key]
        env = report["environment"]
        out.append(f"**{title}** (`{report['command']}`; bench process: {report['process']['seconds']:.0f} s wall, "
                   f"peak RSS {report['process']['peak_rss_mb']:.0f} MB; load average "
                   f"{env['load_average_start'][0]:.1f} at start, {env['load_average_end'][0]:.1f} at end, "
                   f"{env['cpus']} CPUs)")
        out.append("")
        out += [head, sep, *_rows(report), ""]
    blas = results["blas"]
    o, d = blas["one thread"], blas["one per CPU"]
    out.append(f"**BLAS threads.** `mcz compress $DATA/cmu/07` (3,657 frames): {o['seconds']:.1f} s with mcz's "
               f"default of one BLAS thread per process, {d['seconds']:.1f} s with one BLAS thread per CPU "
               f"({d['seconds'] / o['seconds']:.2f} x), peak RSS {o['peak_rss_mb']:.0f} / {d['peak_rss_mb']:.0f} MB. "
               "mcz parallelises with worker processes (`-j`); BLAS threads inside each of them oversubscribe "
               "the CPUs, so `mcz` sets `OPENBLAS_NUM_THREADS=OMP_NUM_THREADS=MKL_NUM_THREADS=1` unless the "
               "environment already sets them.")
    out.append("")
    out += [memory_paragraph(results["memory"]), ""]
    return "\n".join(out)


def memory_paragraph(memory: dict) -> str:
    kept, none, twice = (memory["runs"][name] for name in ("default cache", "no cache", "no cache, set twice"))
    return (f"**Bounded memory.** `mcz compress` keeps clips in memory between its passes while they fit in "
            f"`--cache-mb` ({DEFAULT_CACHE_MB} by default) and reads the others again. On the shared CMU set "
            f"({kept['frames']:,} frames, `-j {memory['jobs']}`): peak RSS {kept['peak_rss_mb']:.0f} MB in "
            f"{kept['seconds']:.0f} s with the default cache, {none['peak_rss_mb']:.0f} MB in {none['seconds']:.0f} s "
            f"with `--cache-mb 0`; the set twice over ({twice['frames']:,} frames) with `--cache-mb 0`: "
            f"{twice['peak_rss_mb']:.0f} MB in {twice['seconds']:.0f} s. Memory follows the cache, not the size "
            "of the database.")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--out", type=Path, default=Path("bench-out"))
    parser.add_argument("--whole", type=Path, help="a whole-CMU report from ratio_distortion.py (skips that run)")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    whole = json.loads(args.whole.read_text()) if args.whole else None
    if whole is not None and "process" not in whole:
        parser.error("--whole needs a report written by ratio_distortion.py (it records the bench process)")
    results = run(args.data, args.out, whole, args.jobs, log=lambda m: print(m, file=sys.stderr, flush=True))
    print(markdown(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())

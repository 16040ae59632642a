"""Regenerate docs/benchmarks.md and its plots in one go.

    python benchmarks/make_docs.py [--data ../shared/data] [--docs docs] [--work bench-out] [-j 2]

Runs, in order: speed.py (compress and decompress of the shared CMU set beside xz and zstd, cold
and warm, -j 1 and -j 2: first, while the machine is quietest), ratio_distortion.py (the whole
shared CMU set and the curves), speed_memory.py (largest clips, BLAS threads, bounded memory; the
whole-set speed comes from the previous run), small_sets.py and one_clip.py (fixed costs: sets of
a few clips per subject, and one clip per archive against Hou et al.) and thesis_tables.py
(tables 4.1 to 4.4). Every number on the page comes from these runs; the page
records the command, the git commit and this run's own output.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

# Before numpy is imported anywhere (here or in a child): one BLAS thread per process. See
# speed_memory.py for the measurement behind this; the page states it.
for _var in BLAS_THREAD_VARIABLES:
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import shlex  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

import one_clip  # noqa: E402
import ratio_distortion  # noqa: E402
import small_sets  # noqa: E402
import speed  # noqa: E402
import speed_memory  # noqa: E402
import thesis_tables  # noqa: E402
from mocapzip.archive import Settings  # noqa: E402
from mocapzip.classes import by_name  # noqa: E402
from mocapzip.cli.choices import MAX_TO_MEAN  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    parser.add_argument("--docs", type=Path, default=REPO / "docs")
    parser.add_argument("--work", type=Path, default=Path(os.environ.get("TMPDIR", "/tmp")) / "mcz-bench-out",
                        help="folder for the raw JSON and CSV reports")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--quick", action="store_true",
                        help="a small subset, to check the pipeline; the page then says it is not the real run")
    args = parser.parse_args(argv)
    try:  # the curves need it: fail now, not after the long whole-set run
        import matplotlib  # noqa: F401
    except ImportError:
        parser.error("the plots need matplotlib: pip install -e '.[plot]'")

    from mocapzip import __version__
    from mocapzip.bench.runner import RULES, _git_state

    log_lines: list[str] = []
    started = time.time()

    def log(message: str) -> None:
        stamp = f"[{time.time() - started:6.0f} s] "
        for line in str(message).splitlines() or [""]:
            log_lines.append(stamp + line)
            print(stamp + line, file=sys.stderr, flush=True)

    git = _git_state()
    data = args.data.resolve()
    log(f"mocapzip {__version__}, commit {git['commit'] if git else 'unknown'}"
        + (" with uncommitted changes" if git and git["uncommitted_changes"] else ""))
    log(f"data: {data}; BLAS threads: 1 per process; jobs: {args.jobs}")
    log("== speed: compress and decompress beside xz and zstd")
    sp = speed.run(data, "cmu/07" if args.quick else "cmu", log)
    (args.work / "speed.json").parent.mkdir(parents=True, exist_ok=True)
    (args.work / "speed.json").write_text(json.dumps(sp, indent=1) + "\n")
    log("== warm-up: mcz's kernels compiled into its cache, so the runs below are warm (speed.py's cold start "
        "used a cache of its own)")
    with tempfile.TemporaryDirectory() as warm:
        clip = data / "cmu" / "07" / "07_01.amc"
        for warm_up in (speed.mcz("compress", str(clip), "-o", f"{warm}/w.mcz", "-q"),
                        speed.mcz("decompress", f"{warm}/w.mcz", "-o", f"{warm}/out", "-q")):
            subprocess.run(warm_up, check=True)
    log("== ratio and distortion: whole shared CMU set, and curves")
    rd = ratio_distortion.run(data, args.work, args.docs, args.jobs, log, quick=args.quick)
    log("== speed and memory")
    sm = speed_memory.run(data, args.work, rd["whole"], args.jobs, log, quick=args.quick)
    log("== fixed costs: small sets, and one clip per archive")
    runs = [(classes, by_name.POOL_FRAMES, Settings().basis_precision)
            for classes in (("pooled",) if args.quick else ("pooled", "subject", "single"))]
    fc = {"small_sets": small_sets.run(runs, args.jobs, show=log, data=data / "cmu"),
          "one_clip": one_clip.run(data, args.jobs, limit=4 if args.quick else None)}
    log(fc["one_clip"])
    log("== thesis tables 4.1 to 4.4")
    tt = thesis_tables.run_tables(data, args.jobs, log, quick=args.quick)
    (args.work / "thesis_tables.json").write_text(json.dumps(tt, indent=1) + "\n")
    head = ratio_distortion.headline(rd)
    elapsed = time.time() - started
    log(f"done in {elapsed / 60:.1f} min")
    for e in sorted(head["bytes_per_frame"], reverse=True):
        h, hs = head["mcz_over_hou"][e], head["mcz_over_hou_shared"][e]
        log(f"mcz {e:g} cm: {head['bytes_per_frame'][e]:.2f} bytes/frame for the whole set; per clip mcz/Hou "
            f"median {h['median']:.3f}, worst {h['worst']:.3f} (basis per subject: median {hs['median']:.3f}, "
            f"worst {hs['worst']:.3f}); encode {head['vs_xz'][e]['encode_speed']:.2f} x, "
            f"decode {head['vs_xz'][e]['decode_speed']:.2f} x the speed of xz -9")

    command = "python benchmarks/make_docs.py" + ("" if argv is None and len(sys.argv) == 1 else
                                                  " " + shlex.join(sys.argv[1:] if argv is None else argv))
    page = portable(render(command, git, elapsed, rd, sm, sp, tt, fc, head, RULES, log_lines, data), data, args.work)
    (args.docs / "benchmarks.md").write_text(page + kept(args.docs / "benchmarks.md"))
    print(f"wrote {args.docs / 'benchmarks.md'}", file=sys.stderr)
    return 0


def portable(page: str, data: Path, work: Path) -> str:
    """`page` with this machine's paths as the page names them: the data folder as `$DATA`, the
    reports' as `$WORK`, the repository's files relative to it (commands anyone can rerun)."""
    for path, shown in ((work, "$WORK"), (data, "$DATA"), (REPO, ".")):
        for spelled in {str(path), str(path.resolve())}:
            page = page.replace(spelled + "/", shown + "/" if shown != "." else "").replace(spelled, shown)
    return page


KEPT = "<!-- Kept by benchmarks/make_docs.py"


def kept(page: Path) -> str:
    """The page's sections from the KEPT marker on: measured by commands of their own (each section names
    its command), which take other runs than this one's; carried over as they are."""
    text = page.read_text() if page.exists() else ""
    return "" if KEPT not in text else "\n" + text[text.index(KEPT):]


def render(command, git, elapsed, rd, sm, sp, tt, fc, head, rules, log_lines, data) -> str:
    whole = rd["whole"]
    env = whole["environment"]
    commit = git["commit"] if git else "unknown"
    dirty = " (with uncommitted changes in the working tree)" if git and git["uncommitted_changes"] else ""
    errors = sorted(head["bytes_per_frame"], reverse=True)
    out = ["# Benchmarks", "",
           *(["**QUICK RUN (--quick): a subset to check the pipeline. These are not the benchmark numbers.**", ""]
             if "--quick" in command else []),
           "<!-- Generated by benchmarks/make_docs.py: do not edit by hand; rerun the command below. -->", "",
           f"Every number on this page up to its run's output was produced by one command, `{command}` "
           f"({elapsed / 60:.0f} min), at commit `{commit}`{dirty}, on {whole['started'][:10]}: "
           f"Python {env['python']}, NumPy {env['numpy']}, {env['cpus']} CPUs shared with other work "
           f"(load average {env['load_average_start'][0]:.1f} when the whole-set run started), one BLAS thread per "
           f"process. Data: the shared real data set (`$DATA/cmu`, `$DATA` = `../shared/data`; CMU, 120 Hz; never copied into "
           "the repository). "
           "Raw reports (JSON, CSV) are written to `--work` (`$WORK`); `mcz bench` produces the same report for any input.", "",
           "## Summary", ""]
    h = head
    for e in errors:
        c, cs = h["mcz_over_hou"][e], h["mcz_over_hou_shared"][e]
        v = h["vs_xz"][e]
        out.append(f"* **{e:g} cm** (mean joint error of every clip, measured end to end; every joint of every frame "
                   f"within {MAX_TO_MEAN * e:g} cm, compress's default `--max-error`): the shared CMU set "
                   f"({whole['runs'][0]['overall']['clips']} clips, {whole['runs'][0]['overall']['frames']:,} frames) "
                   f"as one archive takes **{h['bytes_per_frame'][e]:.2f} bytes per frame** "
                   f"({h['ratio_amc'][e]:.0f} x smaller than the AMC text; xz -9: {h['xz_bytes_per_frame']:.1f} bytes "
                   f"per frame). Per clip, mcz bytes / Hou et al. bytes at the same target: median "
                   f"**{c['median']:.3f}**, worst **{c['worst']:.3f}** ({c['worst_clip']}) against Hou et al. coding "
                   f"each clip alone; median **{cs['median']:.3f}**, worst **{cs['worst']:.3f}** ({cs['worst_clip']}) "
                   f"against Hou et al. with one basis per subject. Speed against xz -9 in the same run: encode "
                   f"**{v['encode_speed']:.2f} x**, decode **{v['decode_speed']:.2f} x** (above 1: mcz is faster).")
    rows = {row["name"]: row for row in sp["rows"]}
    fastest_decompress = max((r for r in sp["rows"] if r["name"].startswith("mcz decompress")),
                             key=lambda r: r["frames_per_second"])
    out.append(f"* **Speed** ({sp['set']}, 1 cm, `python benchmarks/speed.py`): compress with `-j 2` "
               f"**{rows['mcz compress -j 2']['frames_per_second']:,.0f} frames/s** "
               f"({rows['mcz compress -j 2']['vs_xz']:.2f} x the speed of xz -9 in the same run), decompress "
               f"**{fastest_decompress['frames_per_second']:,.0f} frames/s** ({fastest_decompress['name']}; "
               f"{fastest_decompress['vs_xz']:.2f} x xz -d). The first run after installing compiles mcz's kernels: "
               f"{rows['mcz compress -j 1, cold start']['seconds'] - rows['mcz compress -j 1']['seconds']:.0f} s more.")
    out += ["", "How to read these: mcz shares one PCA basis per subject across clips (subjects under 4,000 frames "
            "share one between them: `--classes pooled`, docs/fixed_costs.md) and the archive's metadata "
            "across all clips. Hou et al. section IV codes each clip alone with its own basis (the paper's "
            "per-sequence results), so against it mcz's per-clip numbers include the advantage of sharing; the "
            "'basis per subject' variant (section V with K = 1 per subject) shares as mcz does, and is the "
            "like-for-like comparison.", ""]
    out += ["PPCA class recognition (thesis tables 4.5 to 4.8) and `--classes auto` have their own page, "
            "[classification.md](classification.md), written by `python benchmarks/classification.py`.", ""]
    out += ["## How it is measured", "", rules, ""]
    out += ["## (a) O'Kane's thesis, tables 4.1 to 4.4, rerun", "",
            thesis_tables.__doc__.split("\n\n", 2)[2].strip(), "",
            thesis_tables.markdown(tt)]
    out += ["## (b) mcz vs Hou et al. 2015 vs xz -9 / zstd -19: ratio and distortion", "",
            ratio_distortion.markdown(rd, Path("docs"))]
    out += ["## (c) Speed and peak memory", "", "**Speed table** (`python benchmarks/speed.py`)", "",
            speed.markdown(sp), "", speed_memory.markdown(sm)]
    out += ["## (d) Fixed costs: small sets, and one clip per archive", "",
            "What an archive pays however few frames it holds (skeletons, class bases, meta, priors, container; "
            "[fixed_costs.md](fixed_costs.md)). Sets of links into the shared CMU set, at 1 cm "
            "(`python benchmarks/small_sets.py --classes pooled,subject,single`):", "",
            *fc["small_sets"], "", "Every CMU clip under 1,000 frames, each compressed alone, against Hou et al. coding "
            "it alone (`python benchmarks/one_clip.py`):", "", fc["one_clip"], ""]
    out += ["## Output of the run", "", "```", *log_lines, "```", ""]
    return "\n".join(out)


if __name__ == "__main__":
    sys.exit(main())

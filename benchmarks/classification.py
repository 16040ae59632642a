"""PPCA class recognition (thesis 3.2.4, tables 4.5 to 4.8) and automatic classes, on the shared data.

    python benchmarks/classification.py [--data ../shared/data] [--out docs/classification.md]
                                        [--json FILE] [--skip-compression] [-j 2]

1. CMU walk / run / boxing, trained on some subjects and tested on others (two folds,
   the training and test subjects swapped), for every representation: the table in the
   thesis layout (rows: class models, columns: test clips by class, cells: % of test
   poses above the automatic threshold), plus the share of poses and of clips whose
   most-voted class is the true one.
2. HDM05, 11 classes x 3 actors: train on two actors, test on the third (three folds).
3. `--classes auto` against `single` and `subject`: bytes per frame of real archives
   (`mocapzip.archive.compress`) on a mixed subset.

Classes and clips come from MANIFEST.tsv (`class` column). Writes a Markdown page (and,
with --json, every report). Each number on the page is from this run.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # one BLAS thread per process
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
REPRESENTATIONS = ("normalised", "aligned", "scaled", "channels", "positions")
CMU_CLASSES = ("walk", "run", "boxing")
# Subjects with walk, run or boxing clips: 02 (all three), 05, 07, 35, 49, 55 (walk), 09, 35 (run), 13, 14 (boxing).
# 13_29 / 13_30 mix jumping jacks, squats and a jog: left out.
CMU_FOLDS = {
    "A": {"train": ["35", "13"], "test": ["02", "05", "07", "09", "14", "49", "55"]},
    "B": {"train": ["07", "09", "14"], "test": ["02", "05", "13", "35", "49", "55"]},
}
HDM_ACTORS = ("bd", "bk", "dg")
COMPRESSION_SET = ["cmu/02", "cmu/07", "cmu/09", "cmu/35", "cmu/64", "hdm05/bd"]  # mixed classes and subjects
EXCLUDED = {"cmu/13/13_29.amc", "cmu/13/13_30.amc"}


def manifest(data: Path) -> dict[str, str]:
    with open(data / "MANIFEST.tsv", newline="", encoding="utf-8") as f:
        return {r["file"]: r["class"] for r in csv.DictReader(f, delimiter="\t") if r["class"]}


def cmu_files(data: Path, labels: dict[str, str], subjects, classes) -> list[Path]:
    return [data / f for f, c in sorted(labels.items())
            if f.startswith("cmu/") and f.split("/")[1] in subjects and c in classes and f not in EXCLUDED]


def run_fold(data, train, test, representation, only):
    from mocapzip.cli.classify import run_classification

    return run_classification(str(data / "MANIFEST.tsv"), train, test, representation, "auto", 0.99, set(only))


def fmt(v):
    return "-" if v is None else f"{v:.1f}"


def md_table(report, caption, order=None):
    """The thesis layout; `order` (class names) sorts rows and columns as the thesis does (walk, run, boxing)."""
    t = report["table"]
    rows = [r for r in order if r in t["rows"]] if order else t["rows"]
    cols = [c for c in order if c in t["columns"]] if order else t["columns"]
    lines = [f"{caption}", "", "| | " + " | ".join(f"Test {c}" for c in cols) + " |", "|---|" + "---:|" * len(cols)]
    for name in rows:
        row = t["share"][t["rows"].index(name)]
        cells = [row[t["columns"].index(c)] for c in cols]
        cells = [f"**{v:.2f}**" if c == name else f"{v:.2f}" for v, c in zip(cells, cols)]
        lines.append(f"| {name} class | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def summary_row(name, report):
    return (f"| {name} | {report['threshold']:.0f} | {fmt(report['diagonal_mean'])} | {fmt(report['off_diagonal_mean'])} "
            f"| {fmt(report['pose_accuracy'])} | {fmt(report['clip_accuracy'])} |")


SUMMARY_HEAD = ("| representation | threshold | diagonal mean % | off-diagonal mean % | poses best-class correct % "
                "| clips best-class correct % |\n|---|---:|---:|---:|---:|---:|")


def classification_sections(data: Path, results: dict) -> list[str]:
    labels = manifest(data)
    out = ["## 1. CMU walk / run / boxing across subjects (thesis tables 4.5 to 4.8)", ""]
    out.append("Each class is one PPCA model (Q components holding 99 % of its training poses' variance, "
               "rho the mean of the remaining eigenvalues, thesis eq. 3.10 to 3.13). Cells: % of the test "
               "poses of a column whose log density under the row's model is above the threshold. The "
               "threshold is the thesis's automatic one: test poses lie above it for one class on average "
               "(each table sums to columns x 100 %). \"Best class\": the class with the highest density "
               "for the most poses of a clip (no threshold).")
    out.append("")
    for fold, spec in CMU_FOLDS.items():
        train = cmu_files(data, labels, spec["train"], CMU_CLASSES)
        test = cmu_files(data, labels, spec["test"], CMU_CLASSES)
        counts = {c: sum(labels[str(p.relative_to(data))] == c for p in test) for c in CMU_CLASSES}
        tcounts = {c: sum(labels[str(p.relative_to(data))] == c for p in train) for c in CMU_CLASSES}
        out.append(f"### Fold {fold}: train on subjects {', '.join(spec['train'])}; test on {', '.join(spec['test'])}")
        out.append("")
        out.append("Training clips: " + ", ".join(f"{c} {tcounts[c]}" for c in CMU_CLASSES)
                   + "; test clips: " + ", ".join(f"{c} {counts[c]}" for c in CMU_CLASSES) + ".")
        out.append("")
        rows = []
        for rep in REPRESENTATIONS:
            started = time.perf_counter()
            report = run_fold(data, train, test, rep, CMU_CLASSES)
            results.setdefault("cmu", {}).setdefault(fold, {})[rep] = report
            print(f"cmu fold {fold} {rep}: diag {report['diagonal_mean']:.1f} off {report['off_diagonal_mean']:.1f} "
                  f"poses {report['pose_accuracy']:.1f} clips {report['clip_accuracy']:.1f} "
                  f"({time.perf_counter() - started:.1f} s)", file=sys.stderr)
            rows.append(summary_row(rep, report))
            if rep in ("normalised", "aligned", "channels"):
                q = ", ".join(f"{n} Q={c['components']}" for n, c in report["classes"].items())
                out.append(md_table(report, f"**{rep}** (threshold {report['threshold']:.0f}; {q})", CMU_CLASSES))
                out.append("")
        out.append(SUMMARY_HEAD)
        out.extend(rows)
        out.append("")
    return out


def hdm_sections(data: Path, results: dict) -> list[str]:
    labels = manifest(data)
    out = ["## 2. HDM05: 11 classes, train on two actors, test on the third", ""]
    out.append("One clip per class and actor (bk has two `sneak` clips). Same models, threshold and measures as above.")
    out.append("")
    classes = sorted({c for f, c in labels.items() if f.startswith("hdm05/")})
    pooled: dict[str, list] = {}
    for held_out in HDM_ACTORS:
        train = [data / "hdm05" / a for a in HDM_ACTORS if a != held_out]
        test = [data / "hdm05" / held_out]
        out.append(f"### Test actor {held_out} (train on {', '.join(a for a in HDM_ACTORS if a != held_out)})")
        out.append("")
        rows = []
        for rep in REPRESENTATIONS:
            report = run_fold(data, train, test, rep, classes)
            results.setdefault("hdm05", {}).setdefault(held_out, {})[rep] = report
            pooled.setdefault(rep, []).append(report)
            print(f"hdm05 {held_out} {rep}: diag {report['diagonal_mean']:.1f} off {report['off_diagonal_mean']:.1f} "
                  f"poses {report['pose_accuracy']:.1f} clips {report['clip_accuracy']:.1f}", file=sys.stderr)
            rows.append(summary_row(rep, report))
            if rep == "normalised":
                out.append(md_table(report, f"**normalised** (threshold {report['threshold']:.0f})"))
                out.append("")
        out.append(SUMMARY_HEAD)
        out.extend(rows)
        out.append("")
    out.append("### HDM05, mean over the three test actors")
    out.append("")
    out.append("| representation | diagonal mean % | off-diagonal mean % | poses best-class correct % | clips best-class correct % |")
    out.append("|---|---:|---:|---:|---:|")
    for rep, reports in pooled.items():
        out.append(f"| {rep} | " + " | ".join(fmt(float(np.mean([r[k] for r in reports]))) for k in
                                             ("diagonal_mean", "off_diagonal_mean", "pose_accuracy", "clip_accuracy")) + " |")
    out.append("")
    return out


def compress_subset(data: Path, mode: str, work: Path, jobs: int, error_cm: float = 1.0) -> dict:
    """One real archive of COMPRESSION_SET with --classes `mode`."""
    from mocapzip import archive
    from mocapzip import progress

    progress.set_quiet(True)
    inputs = [data / p for p in COMPRESSION_SET]
    out = work / f"{mode.replace(':', '_')}.mcz"
    settings = archive.Settings(error_cm=error_cm, classes=mode)
    summary = archive.compress(inputs, out, settings, force=True, jobs=jobs)
    with archive.Archive(out) as opened:
        meta = opened.meta
        sizes = opened.stream_sizes()
    summary["classes"] = [{k: c[k] for k in ("name", "clips", "frames", "components")} for c in meta["classes"]]
    summary["members"] = {c["name"]: [r["path"] for r in meta["clips"] if r["class"] == i]
                          for i, c in enumerate(meta["classes"])}
    summary["stream_bytes"] = {k: sum(v for n, v in sizes.items() if n.split("/")[0] == k) for k in ("class", "clip")}
    summary["auto"] = meta.get("auto_classes")
    return summary


def compression_sections(data: Path, results: dict, jobs: int) -> list[str]:
    labels = manifest(data)
    work = Path(tempfile.mkdtemp(prefix="mcz-autoclass-"))
    out = ["## 3. Automatic classes: bytes per frame of real archives", ""]
    files = [f for f in labels if any(f.startswith(p + "/") for p in COMPRESSION_SET) and f.lower().endswith(".amc")]
    frames_by_class: dict[str, int] = {}
    with open(data / "MANIFEST.tsv", newline="", encoding="utf-8") as f:
        for r in csv.DictReader(f, delimiter="\t"):
            if r["file"] in files:
                frames_by_class[r["class"]] = frames_by_class.get(r["class"], 0) + int(r["frames"])
    out.append(f"Subset: {', '.join(COMPRESSION_SET)} ({len(files)} clips; frames by MANIFEST class: "
               + ", ".join(f"{c} {n}" for c, n in sorted(frames_by_class.items())) + "). `mcz compress -e 1` "
               "(aligned, DCT), every clip within 1 cm mean joint error end to end. `auto` chose K by the "
               "byte estimate; `auto:K` forces K.")
    out.append("")
    out.append("| --classes | classes | bytes | bytes/frame | class streams | clip streams | worst clip error cm | seconds |")
    out.append("|---|---:|---:|---:|---:|---:|---:|---:|")
    summaries = {}
    for mode in ("single", "subject", "auto", "auto:2", "auto:4", "auto:6"):
        started = time.perf_counter()
        s = compress_subset(data, mode, work, jobs)
        summaries[mode] = s
        print(f"compress {mode}: {s['output_bytes']} B, {s['bytes_per_frame']:.3f} B/frame, "
              f"{len(s['classes'])} classes ({time.perf_counter() - started:.0f} s)", file=sys.stderr)
        out.append(f"| {mode} | {len(s['classes'])} | {s['output_bytes']:,} | {s['bytes_per_frame']:.3f} | "
                   f"{s['stream_bytes']['class']:,} | {s['stream_bytes']['clip']:,} | {s['worst_error_cm']:.3f} | "
                   f"{s['seconds']:.0f} |")
    results["compression"] = summaries
    out.append("")
    auto = summaries["auto"]
    if auto.get("auto"):
        g = auto["auto"][0]
        out.append(f"`auto` chose K={g['k']} ({g['method']}); estimated {g['estimated_bytes']:,} B of bases and "
                   f"coefficients. Estimates of the partitions it tried (K, method, bytes):")
        out.append("")
        cands = g.get("candidates") or []
        best = {}
        for c in cands:
            key = (c["k"], c["method"])
            best[key] = min(best.get(key, c["bytes"]), c["bytes"])
        if best:
            out.append("| K | kss (PPCA) | anneal |")
            out.append("|---:|---:|---:|")
            for k in sorted({k for k, _ in best}):
                first = best.get((k, "kss"), best.get((k, "single")))
                cells = [f"{v:,}" if v is not None else "-" for v in (first, best.get((k, "anneal")))]
                out.append(f"| {k} | {cells[0]} | {cells[1]} |")
            out.append("")
        out.append("Automatic classes (MANIFEST class of each member in brackets):")
        out.append("")
        for name, members in auto["members"].items():
            tags = {}
            for m in members:
                key = next((f for f in files if f.endswith("/" + m)), None)
                tags[labels.get(key, "?")] = tags.get(labels.get(key, "?"), 0) + 1
            out.append(f"- {name}: {len(members)} clips (" + ", ".join(f"{c} {n}" for c, n in sorted(tags.items())) + ")")
        out.append("")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "classification.md")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--skip-compression", action="store_true")
    parser.add_argument("--skip-classification", action="store_true")
    parser.add_argument("--note", default=None, help="A line to put under the title (e.g. which codec state was run).")
    parser.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1)
    args = parser.parse_args()
    started = time.perf_counter()
    results: dict = {}
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                                text=True).stdout.strip()
    except OSError:
        commit = "?"
    page = ["# Classification and automatic classes", "",
            f"Generated by `python benchmarks/classification.py` (git {commit}, working tree as run). "
            "Data: the shared real clips (`../shared/data`, MANIFEST.tsv classes).", ""]
    if args.note:
        page += [args.note, ""]
    if not args.skip_classification:
        page += classification_sections(args.data, results)
        page += hdm_sections(args.data, results)
    if not args.skip_compression:
        page += compression_sections(args.data, results, args.jobs)
    page.append(f"Total run time: {time.perf_counter() - started:.0f} s.")
    page.append("")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(page))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=float))
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()

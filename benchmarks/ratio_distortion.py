"""mcz against Hou et al. 2015 and xz -9 / zstd -19: ratio and distortion, per clip, on the shared CMU set.

    python benchmarks/ratio_distortion.py [--data ../shared/data] [--out DIR] [--plot-dir docs]

Two `mcz bench` runs, each in a child process (its peak memory is measured too):

1. the whole shared CMU set as ONE archive per target error (1.0 and 0.5 cm), with
   xz -9, zstd -19 and Hou et al. (best L, k, Q per clip) on the same clips:
   the numbers of the report, and the per-clip comparison;
2. one clip per motion class at four target errors (0.25 to 2 cm), for the
   ratio-distortion curves (`--plot`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
WHOLE_ERRORS = (1.0, 0.5)
CURVE_ERRORS = (0.25, 0.5, 1.0, 2.0)
CURVE_CLIPS = ("07/07_01.amc", "13/13_30.amc", "02/02_05.amc", "05/md_05.amc", "135/135_04.amc")  # walk, run, boxing, dance, martial


def bench_run(args: list[str], out_json: Path, log=print) -> dict:
    """`mcz bench ARGS --json out_json` in a child process; returns the report plus the child's wall time and peak RSS."""
    from mocapzip.bench.runner import mcz_command, run_measured

    argv = [*mcz_command(), *args, "--json", str(out_json)]
    log("$ mcz bench " + " ".join(args + ["--json", out_json.name]))
    result = run_measured(argv, echo=log)
    if result["returncode"] != 0:
        raise SystemExit(f"mcz bench failed with exit code {result['returncode']}")
    report = json.loads(out_json.read_text())
    report["process"] = result
    out_json.write_text(json.dumps(report, indent=1) + "\n")  # with the process's time and memory
    log(f"  {result['seconds']:.0f} s, peak RSS of the bench process {result['peak_rss_mb']:.0f} MB")
    return report


def run(data: Path = DATA, out: Path = Path("."), plot_dir: Path | None = None, jobs: int = 2, log=print,
        quick: bool = False) -> dict:
    """`quick`: one subject folder and two curve clips, to check the pipeline (never for the docs)."""
    out.mkdir(parents=True, exist_ok=True)
    whole_input = data / "cmu" / "07" if quick else data / "cmu"
    curve_clips, curve_errors = (CURVE_CLIPS[:2], CURVE_ERRORS[1:3]) if quick else (CURVE_CLIPS, CURVE_ERRORS)
    whole = bench_run([str(whole_input), *sum((["-e", f"{e:g}"] for e in WHOLE_ERRORS), []), "-j", str(jobs),
                       "--csv", str(out / "cmu.csv"), "-q"], out / "cmu.json", log)
    plot_args = ["--plot", str(plot_dir / "ratio_distortion.png")] if plot_dir else []
    curves = bench_run([*(str(data / "cmu" / c) for c in curve_clips), *sum((["-e", f"{e:g}"] for e in curve_errors), []),
                        "-j", str(jobs), "-q", *plot_args], out / "curves.json", log)
    if plot_dir:
        per_clip_plot(whole, plot_dir / "mcz_vs_hou_per_clip.png")
    return {"whole": whole, "curves": curves}


def runs_by_codec(report: dict, codec: str) -> dict[float, dict]:
    return {r["target_error_cm"]: r for r in report["runs"] if r["codec"] == codec and r["overall"]}


def per_clip_plot(report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    mcz = runs_by_codec(report, "mcz")
    fig, ax = plt.subplots(figsize=(8, 4.8))
    for codec, fill, variant in (("hou", True, "Hou per clip"), ("hou-shared", False, "Hou, basis per subject")):
        hou = runs_by_codec(report, codec)
        for error, marker in zip(sorted(mcz, reverse=True), "os^"):
            if error not in hou:
                continue
            hou_bytes = {c["path"]: c["bytes"] for c in hou[error]["clips"]}
            rows = [(c["frames"], c["bytes"] / hou_bytes[c["path"]]) for c in mcz[error]["clips"] if c["path"] in hou_bytes]
            ax.scatter(*zip(*rows), marker=marker, s=18, alpha=0.7, label=f"vs {variant}, {error:g} cm",
                       **({} if fill else {"facecolors": "none", "edgecolors": f"C{2 + (marker == 's')}"}))
    ax.axhline(1.0, color="grey", linestyle=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("clip length (frames)")
    ax.set_ylabel("mcz bytes / Hou et al. bytes (per clip)")
    ax.set_title("shared CMU set: each clip's bytes in one mcz archive vs Hou et al.", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown(results: dict, doc_dir: Path | None = None) -> str:
    whole, curves = results["whole"], results["curves"]
    mcz, hou, shared = runs_by_codec(whole, "mcz"), runs_by_codec(whole, "hou"), runs_by_codec(whole, "hou-shared")
    lossless = {r["codec"]: r for r in whole["runs"] if r["codec"] in ("xz", "zstd")}
    out = [f"Command: `{whole['command']}` (then `{curves['command']} --plot docs/ratio_distortion.png`).", ""]
    out.append("**Whole shared CMU set** "
               f"({whole['runs'][0]['overall']['clips']} clips, {whole['runs'][0]['overall']['frames']:,} frames, "
               f"{whole['runs'][0]['overall']['amc_bytes'] / 1e6:.1f} MB of AMC). mcz: one archive per target; "
               "Hou et al.: each clip coded alone with its best (L, k, Q), and with one basis per subject "
               "(best L, k per subject, Q per clip); xz / zstd: each AMC file alone.")
    out.append("")
    out.append("| codec | target | bytes/frame (on disk) | payload bytes/frame | ratio vs AMC | vs float32 channels "
               "| vs float32 positions | mean error (cm) | p99 (cm) | max (cm) | skin error | encode frames/s | decode frames/s |")
    out.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for run in [*(mcz[e] for e in sorted(mcz, reverse=True)), *(hou[e] for e in sorted(hou, reverse=True)),
                *(shared[e] for e in sorted(shared, reverse=True)), *lossless.values()]:
        o = run["overall"]
        name = {"mcz": "mcz", "hou": "Hou et al. 2015, per clip", "hou-shared": "Hou et al. 2015, basis per subject",
                "xz": "xz -9", "zstd": "zstd -19"}[run["codec"]]
        target = f"{run['target_error_cm']:g} cm" if run["codec"] not in lossless else "lossless"
        skin = f"{o['skin_error']:.2f}" if o["skin_error"] is not None else "n/a"
        out.append(f"| {name} | {target} | {o['bytes_per_frame']:.2f} | {o['payload_bytes_per_frame']:.2f} | "
                   f"{o['ratio_amc']:.0f} | {o['ratio_f32_channels']:.1f} | {o['ratio_f32_positions']:.1f} | "
                   f"{o['mean_error_cm']:.3f} | {o['p99_error_cm']:.2f} | {o['max_error_cm']:.2f} | {skin} | "
                   f"{o['encode_fps']:,.0f} | {o['decode_fps']:,.0f} |")
    out.append("")
    out.append("Hou et al.'s error is measured on joint positions directly (the codec stores positions, no "
               "rotations, so there is no AMC file and no skin error); its encode speed includes parsing the AMC "
               "and forward kinematics but not its parameter search "
               f"({hou[max(hou)]['search_seconds']:.0f} s per clip, "
               f"{shared[max(shared)]['search_seconds']:.0f} s per subject, for the whole grid over all clips), "
               "and it decodes to positions in memory. mcz and xz / zstd speeds are file to file, measured in "
               "child processes.")
    out.append("")
    out.append("**Per clip, mcz bytes / Hou et al. bytes at the same target error** (below 1: mcz is smaller; "
               "a clip's mcz bytes include its share of the archive's shared streams):")
    out.append("")
    out.append("| target | Hou et al. variant | clips | median | worst (clip) | best (clip) | mcz smaller in | whole set |")
    out.append("|---:|---|---:|---:|---|---|---:|---:|")
    for c in whole["comparisons"]:
        for key, variant in (("mcz_over_hou_bytes", "each clip alone"), ("mcz_over_hou_shared_bytes", "basis per subject")):
            h = c.get(key)
            if h:
                overall = f"{h['overall']:.3f}" if h["overall"] is not None else "-"
                out.append(f"| {c['target_error_cm']:g} cm | {variant} | {h['clips']} | {h['median']:.3f} | "
                           f"{h['worst']:.3f} ({h['worst_clip']}) | {h['best']:.3f} ({h['best_clip']}) | "
                           f"{h['mcz_smaller_in']} of {h['clips']} | {overall} |")
    out.append("")
    out.append("Per motion class (bytes per frame; Hou et al. per clip, mcz in the shared archive):")
    out.append("")
    errors = sorted(mcz, reverse=True)
    out.append("| class | clips | frames | " + " | ".join(f"mcz {e:g} cm | Hou {e:g} cm | Hou/subject {e:g} cm"
                                                       for e in errors) + " | xz -9 |")
    out.append("|---|---:|---:|" + "---:|---:|---:|" * len(errors) + "---:|")
    for g, s in mcz[errors[0]]["classes"].items():
        cells = []
        for e in errors:
            cells.append(f"{mcz[e]['classes'][g]['bytes_per_frame']:.2f}")
            for variant in (hou, shared):
                hs = variant[e]["classes"].get(g) if e in variant else None
                cells.append(f"{hs['bytes_per_frame']:.2f}" if hs else "-")
        xz = lossless["xz"]["classes"][g]["bytes_per_frame"] if "xz" in lossless else float("nan")
        out.append(f"| {g} | {s['clips']} | {s['frames']:,} | " + " | ".join(cells) + f" | {xz:.1f} |")
    out.append("")
    if doc_dir is not None:
        out.append("![ratio-distortion](ratio_distortion.png)")
        out.append("")
        out.append("Ratio-distortion curves: the five clips of the curve run (walk 07_01, run 13_30, boxing 02_05, "
                   "dance md_05, martial arts 135_04) as one archive per target error (0.25, 0.5, 1 and 2 cm); left "
                   "all five, right per class. Dotted lines: xz -9 and zstd -19 (lossless).")
        out.append("")
        out.append("![per clip](mcz_vs_hou_per_clip.png)")
        out.append("")
    out.append("<details><summary>Per clip (bytes per frame; ratio = mcz / Hou)</summary>")
    out.append("")
    out.append("| clip | class | frames | " + " | ".join(f"mcz {e:g} | Hou {e:g} (L, k, Q) | ratio {e:g} | "
                                                      f"Hou/subject {e:g} | ratio {e:g}" for e in errors)
               + " | xz -9 | zstd -19 |")
    out.append("|---|---|---:|" + "---:|---:|---:|---:|---:|" * len(errors) + "---:|---:|")
    clips = {e: {c["path"]: c for c in mcz[e]["clips"]} for e in errors}
    hclips = {e: {c["path"]: c for c in hou[e]["clips"]} for e in errors}
    sclips = {e: {c["path"]: c for c in shared[e]["clips"]} if e in shared else {} for e in errors}
    lclips = {k: {c["path"]: c for c in v["clips"]} for k, v in lossless.items()}
    for path, c in clips[errors[0]].items():
        cells = []
        for e in errors:
            m, h = clips[e][path], hclips[e].get(path)
            cells.append(f"{m['bytes_per_frame']:.2f}")
            if h:
                p = h["hou"]
                cells.append(f"{h['bytes_per_frame']:.2f} ({p['L']}, {p['k']}, {p['Q']})")
                cells.append(f"{m['bytes'] / h['bytes']:.2f}")
            else:
                cells += ["-", "-"]
            sh = sclips[e].get(path)
            cells += [f"{sh['bytes_per_frame']:.2f}", f"{m['bytes'] / sh['bytes']:.2f}"] if sh else ["-", "-"]
        lossless_cells = [f"{lclips[k][path]['bytes_per_frame']:.1f}" if k in lclips else "-" for k in ("xz", "zstd")]
        out.append(f"| {path} | {c['group']} | {c['frames']} | " + " | ".join(cells + lossless_cells) + " |")
    out.append("")
    out.append("</details>")
    out.append("")
    return "\n".join(out)


def headline(results: dict) -> dict:
    """The numbers the summary quotes."""
    whole = results["whole"]
    mcz, hou = runs_by_codec(whole, "mcz"), runs_by_codec(whole, "hou")
    xz = next(r for r in whole["runs"] if r["codec"] == "xz")
    out = {"bytes_per_frame": {e: r["overall"]["bytes_per_frame"] for e, r in mcz.items()},
           "ratio_amc": {e: r["overall"]["ratio_amc"] for e, r in mcz.items()},
           "mcz_over_hou": {c["target_error_cm"]: c.get("mcz_over_hou_bytes") for c in whole["comparisons"]},
           "mcz_over_hou_shared": {c["target_error_cm"]: c.get("mcz_over_hou_shared_bytes") for c in whole["comparisons"]},
           "vs_xz": {c["target_error_cm"]: c.get("vs_xz") for c in whole["comparisons"]},
           "xz_bytes_per_frame": xz["overall"]["bytes_per_frame"],
           "hou_bytes_per_frame": {e: r["overall"]["bytes_per_frame"] for e, r in hou.items()}}
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--out", type=Path, default=Path("bench-out"), help="folder for the JSON and CSV reports")
    parser.add_argument("--plot-dir", type=Path, default=None, help="write ratio_distortion.png and mcz_vs_hou_per_clip.png here")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    results = run(args.data, args.out, args.plot_dir, args.jobs, log=lambda m: print(m, file=sys.stderr, flush=True))
    print(markdown(results, args.plot_dir))
    print(json.dumps(headline(results), indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())

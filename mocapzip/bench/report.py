"""`mcz bench`'s report as people read it: text, CSV and a plot (the JSON is `runner.run_bench`'s dict)."""

from __future__ import annotations

import csv
import io
import itertools

from mocapzip.formats.errors import MocapFormatError

CSV_COLUMNS = ["run", "codec", "label", "target_error_cm", "level", "name", "clips", "frames", "bytes", "payload_bytes",
               "bytes_per_frame", "payload_bytes_per_frame", "ratio_amc", "ratio_f32_channels", "ratio_f32_positions",
               "mean_error_cm", "p99_error_cm", "max_error_cm", "shell_error_cm", "skin_error", "foot_skate_cm_s", "encode_fps", "decode_fps",
               "encode_peak_rss_mb", "decode_peak_rss_mb", "hou_L", "hou_k", "hou_Q"]


def to_csv(report: dict) -> str:
    """One row per run and level: overall, each class, each clip."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, CSV_COLUMNS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for i, run in enumerate(report["runs"]):
        if not run["overall"]:
            continue
        base = {"run": i, "codec": run["codec"], "label": run["label"], "target_error_cm": run["target_error_cm"]}
        writer.writerow({**base, "level": "overall", "name": "all", **_rounded(run["overall"])})
        for name, summary in run["classes"].items():
            writer.writerow({**base, "level": "class", "name": name, **_rounded(summary)})
        for row in run["clips"]:
            hou_params = row.get("hou") or {}
            writer.writerow({**base, "level": "clip", "name": row["path"], "clips": 1, **_rounded(row),
                             "hou_L": hou_params.get("L"), "hou_k": hou_params.get("k"), "hou_Q": hou_params.get("Q")})
    return buf.getvalue()


def _rounded(d: dict) -> dict:
    return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in d.items()}


def format_text(report: dict, per_clip: bool = False) -> str:
    """The terminal report: per run, overall and per class (and per clip on request)."""
    lines = []
    head = (f"{'':<22} {'clips':>5} {'frames':>8} {'B/frame':>8} {'payload':>8} {'xAMC':>7} {'xf32ch':>7} "
            f"{'xf32pos':>7} {'mean cm':>8} {'p99 cm':>7} {'max cm':>7} {'vertex':>7} {'skin':>7} {'skate':>7}")
    for run in report["runs"]:
        lines.append("")
        lines.append(f"== {run['label']}")
        if not run["overall"]:
            lines.append("   no clip met the target")
            continue
        o = run["overall"]
        speed = []
        if o.get("encode_fps"):
            speed.append(f"encode {o['encode_fps']:,.0f} frames/s")
        if o.get("decode_fps"):
            speed.append(f"decode {o['decode_fps']:,.0f} frames/s")
        if o.get("encode_peak_rss_mb"):
            speed.append(f"peak RSS {o['encode_peak_rss_mb']:.0f} MB encode, {o['decode_peak_rss_mb']:.0f} MB decode")
        if speed:
            lines.append("   " + ", ".join(speed))
        if run.get("fixed_bytes"):
            fixed = run["fixed_bytes"]
            total = sum(fixed.values())
            lines.append("   fixed costs: " + ", ".join(f"{name} {size:,} B" for name, size in fixed.items())
                         + f"; {total:,} B, {total / run['archive_bytes']:.1%} of the archive, "
                           f"{total / o['frames']:.2f} bytes/frame")
        lines.append("   errors measured on: " + run["error_measured_on"])
        if o.get("shell_error_cm") is not None:
            lines.append(f"   vertex: worst vertex, cm (ACL's metric, {report['shell_cm']:g} cm shell); "
                         "mean, p99, max: joint error, cm")
        lines.append(head)
        lines.append(_text_row("overall", o))
        for name, summary in run["classes"].items():
            lines.append(_text_row(f"  {name}", summary))
        if per_clip:
            for row in run["clips"]:
                extra = " L={L} k={k} Q={Q}".format(**row["hou"]) if row.get("hou") else ""
                lines.append(_text_row(f"    {row['path']}", {**row, "clips": 1}) + extra)
        if run.get("missing"):
            lines.append(f"   {len(run['missing'])} clips met no grid point (left out): {', '.join(run['missing'][:5])}")
    for c in report["comparisons"]:
        lines.append("")
        text = f"-- {c['mcz']}:"
        for key, name in (("mcz_over_hou_bytes", "Hou"), ("mcz_over_hou_shared_bytes", "Hou (one basis per subject)")):
            if key in c:
                h = c[key]
                text += (f" mcz bytes / {name} bytes per clip at equal target error: median {h['median']:.3f}, "
                         f"worst {h['worst']:.3f} ({h['worst_clip']}); mcz smaller in {h['mcz_smaller_in']} of "
                         f"{h['clips']}.")
        if "vs_xz" in c:
            v = c["vs_xz"]
            text += f" vs xz -9: {v['bytes']:.4f} x the bytes"
            if v["encode_speed"]:
                text += f", {v['encode_speed']:.2f} x the encode speed, {v['decode_speed']:.2f} x the decode speed"
            text += "."
        lines.append(text)
    return "\n".join(lines).lstrip("\n")


def _text_row(name: str, s: dict) -> str:
    skin = f"{s['skin_error']:>7.2f}" if s.get("skin_error") is not None else f"{'-':>7}"
    skate = f"{s['foot_skate_cm_s']:>7.2f}" if s.get("foot_skate_cm_s") is not None else f"{'-':>7}"
    vertex = f"{s['shell_error_cm']:>7.2f}" if s.get("shell_error_cm") is not None else f"{'-':>7}"
    name = name if len(name) <= 22 else name[:21] + "…"
    return (f"{name:<22} {s.get('clips', 1):>5} {s['frames']:>8} {s['bytes_per_frame']:>8.2f} "
            f"{s['payload_bytes_per_frame']:>8.2f} {s['ratio_amc']:>7.0f} {s['ratio_f32_channels']:>7.1f} "
            f"{s['ratio_f32_positions']:>7.1f} {s['mean_error_cm']:>8.3f} {s['p99_error_cm']:>7.2f} "
            f"{s['max_error_cm']:>7.2f} {vertex} {skin} {skate}")


def series_name(run: dict) -> str:
    """The curve a run's point is on: its codec and settings but the error target and the bound on
    every joint, which follows the target (5 x -e by default), so that a sweep's -e 1 and -e 0.5 join."""
    if run["codec"] == "hou":
        return "Hou et al. 2015 (best L, k, Q per clip)"
    if run["codec"] == "hou-shared":
        return "Hou et al. 2015 (one basis per subject)"
    settings = [part for part in run["label"].split(", ")[1:] if not part.startswith("every joint <=")]
    return ", ".join(["mcz", *settings])


def plot(report: dict, path) -> None:
    """Ratio-distortion curves: compression ratio (vs AMC text) against mean joint error."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import matplotlib.ticker
    except ImportError:
        raise MocapFormatError("--plot needs matplotlib: pip install 'mocapzip[plot]'") from None
    runs = [r for r in report["runs"] if r["overall"]]
    groups = sorted({g for r in runs for g in r["classes"]})
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    series: dict[str, list] = {}
    for r in runs:
        if r["codec"] in ("mcz", "hou", "hou-shared"):
            series.setdefault(series_name(r), []).append(r)
    markers = itertools.cycle("os^Dv<>p")
    for name, members in series.items():
        members.sort(key=lambda r: r["target_error_cm"])
        marker = next(markers)
        axes[0].plot([r["overall"]["mean_error_cm"] for r in members], [r["overall"]["ratio_amc"] for r in members],
                     marker=marker, label=name)
        colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
        for j, g in enumerate(groups):
            pts = [(r["classes"][g]["mean_error_cm"], r["classes"][g]["ratio_amc"]) for r in members if g in r["classes"]]
            if pts:
                axes[1].plot(*zip(*pts), marker=marker, color=colours[j % len(colours)],
                             linestyle="-" if name.startswith("mcz") else ("--" if "per clip" in name else ":"),
                             label=g if name == next(iter(series)) else None)
    for r in runs:
        if r["codec"] in ("xz", "zstd"):
            y = r["overall"]["ratio_amc"]
            axes[0].axhline(y, linestyle=":", color="grey" if r["codec"] == "xz" else "black")
            axes[0].annotate(f"{r['label'].split(' (')[0]} (lossless): {y:.2f} x", (0.0, y), textcoords="offset points",
                             xytext=(4, 4 if r["codec"] == "xz" else -11), fontsize=8)
    axes[0].set_title(f"all clips ({runs[0]['overall']['clips'] if runs else 0}), one archive per run")
    axes[1].set_title("per motion class\n(solid: mcz; dashed: Hou per clip; dotted: Hou, basis per subject)", fontsize=10)
    for ax in axes:
        ax.set_xlabel("mean joint error (cm)")
        ax.set_ylabel("compression ratio vs AMC text")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlim(left=0)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

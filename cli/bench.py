"""`mcz bench`: the report people choose a compressor by."""

from __future__ import annotations

import json
import os

import click

from mocapzip.cli import importing
from mocapzip.cli.choices import MAX_TO_MEAN, REPRESENTATIONS, TRANSFORMS, UNITS, max_error_value
from mocapzip.cli.errors import reports_errors
from mocapzip.defaults import ACL_SHELL_CM, AUTO_REPRESENTATION

CODEC_CHOICES = ("mcz", "hou", "hou-shared", "xz", "zstd")


def _splits(values):
    out = []
    for text in values:
        try:
            parts = [float(p) for p in text.split(",")]
        except ValueError:
            parts = []
        if len(parts) != 3 or min(parts) < 0 or sum(parts) <= 0:
            raise click.BadParameter(f"{text!r}: expected three non-negative shares R,P,T, e.g. 0,0.5,0.5",
                                     param_hint="--split")
        out.append(parts)
    return out or [None]


def _codecs(values):
    out = []
    for text in values:
        for name in text.split(","):
            name = name.strip().lower()
            if name not in CODEC_CHOICES:
                raise click.BadParameter(f"{name!r}: choose from {', '.join(CODEC_CHOICES)}", param_hint="--codec")
            if name not in out:
                out.append(name)
    return out or list(CODEC_CHOICES)


@click.command()
@click.argument("inputs", nargs=-1, required=True, type=click.Path())
@click.option("-e", "--error", "errors", multiple=True, type=click.FloatRange(min=0, min_open=True), metavar="CM",
              help="Target mean joint error in cm (repeat for a sweep; default 1.0). Hou et al. get the same targets.")
@click.option("-r", "--representation", "representations", multiple=True,
              type=click.Choice((AUTO_REPRESENTATION, *REPRESENTATIONS)),
              help="What mcz compresses (repeat for a sweep; default auto, as mcz compress: each run names the "
                   "one it resolves to).")
@click.option("-t", "--transform", "transforms", multiple=True, type=click.Choice(TRANSFORMS),
              help="Temporal transform (repeat for a sweep; default dct-edges).")
@click.option("--wavelet", default="db4", show_default=True, help="Wavelet for --transform dwt.")
@click.option("-c", "--classes", "classes", multiple=True, metavar="MODE",
              help="PCA classes: pooled (as compress), single, subject, clip (one per clip), none (no PCA: "
                   "bench-only emulation) or FILE.csv (repeat for a sweep; default pooled).")
@click.option("--split", "splits", multiple=True, metavar="R,P,T",
              help="Forced error split between root, PCA and temporal coding (repeat for a sweep).")
@click.option("--codec", "codecs", multiple=True, metavar="NAME[,NAME]",
              help="Codecs to run: mcz, hou (Hou et al. 2015, each clip alone), hou-shared (Hou et al., one "
                   "basis per subject), xz (-9), zstd (-19). Default: all five.")
@click.option("--groups", type=click.Path(dir_okay=False), default=None,
              help="Table of clip -> motion class for the per-class report (CSV/TSV with file and class "
                   "columns; default: a MANIFEST.tsv in or above the inputs, else the skeleton).")
@click.option("--asf", type=click.Path(dir_okay=False), help="Skeleton for every AMC (default: the .asf in each AMC's folder; of several different ones, the one whose name begins the AMC's).")
@click.option("--units", type=click.Choice(UNITS), default=None,
              help="Unit of the lengths in BVH files (default: inferred from the skeleton's size, as compress does).")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=os.cpu_count() or 1, show_default="all cores",
              help="Worker processes for mcz's error search.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, allow_dash=True), help="Write the full report as JSON ('-': stdout).")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, allow_dash=True), help="Write one row per run and clip/class/overall.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Draw ratio-distortion curves (PNG; needs mocapzip[plot]).")
@click.option("--max-error", "max_error", metavar="CM|none", callback=max_error_value, default=None,
              help="mcz's bound on every joint of every frame, as compress takes it. Default: as compress, "
                   f"{MAX_TO_MEAN:g} x each -e; 'none': no bound.")
@click.option("--contact-error", "contact_error", metavar="CM|none", callback=max_error_value, default=None,
              help="mcz's bound on planted foot joints, as compress takes it (default: as compress).")
@click.option("--plant-feet", is_flag=True, help="mcz holds the source's planted feet still, as compress --plant-feet.")
@click.option("--shell-cm", type=click.FloatRange(min=0), default=ACL_SHELL_CM, show_default=True, metavar="CM",
              help="Distance from every bone of the virtual vertices whose worst error is reported (ACL's "
                   "metric, docs/acl.md).")
@click.option("--per-clip", is_flag=True, help="Also print one line per clip.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no table (files are still written).")
@reports_errors
def bench(inputs, errors, representations, transforms, wavelet, classes, splits, codecs, groups, asf, units, jobs,
          json_path, csv_path, plot_path, max_error, contact_error, plant_feet, shell_cm, per_clip, quiet):
    """Compress and decompress the clips under INPUTS and report size, ratio, error and speed,
    per clip, per motion class and overall, next to xz -9, zstd -19 and Hou et al. 2015.

    Errors are measured end to end: decompressed AMC (or BVH) text read back and run through forward
    kinematics (Hou et al. code joint positions, so theirs are measured on positions): the
    mean, 99th percentile and max joint error, mcz's worst vertex by ACL's metric (virtual vertices
    --shell-cm from every bone, in object space: it sees an end bone's twist, which moves no joint),
    and foot skate, how much faster (cm/s) the source's planted feet slide once decoded
    (docs/fidelity.md).
    Several values of -e/-r/-t/-c/--split make a sweep: every combination is one mcz run.

    \b
    Examples:
      mcz bench ../shared/data/cmu/07 --json report.json
      mcz bench ../shared/data/cmu -e 1 -e 0.5 --plot rd.png
      mcz bench ../shared/data/bvh-bandai -e 1 -e 0.5 --codec mcz --codec xz
      mcz bench clips/ -r channels -r positions -c none -c single --split 0,0.5,0.5 --codec mcz
    """
    with importing():
        from mocapzip.bench import report as bench_report
        from mocapzip.bench import runner as bench_module
        from mocapzip import progress

    if plot_path:  # fail before the long run, not after it
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise click.UsageError("--plot needs matplotlib: pip install 'mocapzip[plot]'") from None
    progress.set_quiet(quiet)
    options = bench_module.BenchOptions(
        inputs=list(inputs), errors=list(errors) or [1.0], representations=list(representations) or [AUTO_REPRESENTATION],
        transforms=list(transforms) or ["dct-edges"], classes=list(classes) or ["pooled"], splits=_splits(splits),
        codecs=_codecs(codecs), asf=asf, groups=groups, jobs=jobs, wavelet=wavelet, quiet=quiet, max_error=max_error,
        contact_error=contact_error, plant_feet=plant_feet, units=units, shell_cm=shell_cm)
    report = bench_module.run_bench(options)
    if json_path:
        _write(json_path, json.dumps(report, indent=1) + "\n")
    if csv_path:
        _write(csv_path, bench_report.to_csv(report))
    if plot_path:
        bench_report.plot(report, plot_path)
    if not quiet and json_path != "-" and csv_path != "-":
        click.echo(bench_report.format_text(report, per_clip=per_clip))


def _write(path: str, text: str) -> None:
    if path == "-":
        click.echo(text, nl=False)
        return
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)


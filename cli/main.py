"""The `mcz` command line: click front end over the mocapzip pipeline.

Conventions follow zstd: `-o` names the output, inputs are kept, nothing is
overwritten without `-f`, and exit codes are 0 (success), 1 (bad input, damaged
archive, I/O failure: one line on stderr, never a traceback) and 2 (usage: one line
naming the command and its --help, `cli/errors.py`).
"""

from __future__ import annotations

import errno
import json
import os
from collections import Counter
from contextlib import contextmanager

import click
from click.core import ParameterSource

from mocapzip import __version__
from mocapzip.cli import importing
from mocapzip.cli.bench import bench
from mocapzip.cli.classify import classify
from mocapzip.cli.plots import plot, view
from mocapzip.cli.choices import (MAX_TO_MEAN, REPRESENTATIONS, TRANSFORMS, UNITS, contact_error_cm, max_error_cm,
                                  max_error_value)
from mocapzip.cli.errors import UsageInOneLine, reports_errors
from mocapzip.cluster import LOCAL_WORKERS_PER_CORE, ClusterError, parse_address
from mocapzip.defaults import (ACL_SHELL_CM, AUTO_REPRESENTATION, CHANNELS_BELOW_CM_HZ, CHANNELS_BELOW_VERTEX_CM_HZ,
                               DEFAULT_CACHE_MB, DEFAULT_FPS)


@click.group("mcz", cls=UsageInOneLine, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "-V", "--version", prog_name="mcz")
def main():
    """mcz: compress motion-capture databases (Acclaim ASF/AMC, BVH) into one .mcz archive.

    \b
    Typical use:
      mcz inspect ../shared/data/cmu            what is there: clips, frames, skeletons
      mcz compress ../shared/data/cmu -o db.mcz one archive, every clip within 1 cm
      mcz decompress db.mcz -o out/             the ASF/AMC and BVH files back
      mcz convert clips/ -o bvh/                ASF/AMC to BVH and back, same joint positions

    Run `mcz COMMAND --help` for the options of each command.
    """


def jobs_option(work: str, workers: str = "Worker processes"):
    """-j/--jobs, as every command that spreads its work over the cores takes it."""
    return click.option("-j", "--jobs", type=click.IntRange(min=1), default=os.cpu_count() or 1,
                        show_default="all cores", help=f"{workers} for {work}.")


@main.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path())
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), help="Skeleton for every AMC (default: the .asf in each AMC's folder; of several different ones, the one whose name begins the AMC's).")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Frame rate for durations and the glitch check, for every clip (default: the rate a clip's "
                   "files state, as BVH 'Frame Time:' or Vicon Blade's '# Frame Rate: 200.000 fps', else 120).")
@click.option("--units", type=click.Choice(UNITS), default=None,
              help="Unit of the lengths in BVH files, for --check (default: inferred from the skeleton's size).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--check", is_flag=True,
              help="Also list glitches in the source, per clip, bone and frames: joints that jump faster than "
                   "25 m/s, angles a quarter turn beyond the ASF's limits, values held for 30 frames or more, "
                   "bones zeroed (docs/fidelity.md). They are reported, not errors: the exit code stays 0.")
@reports_errors
def inspect(paths, asf, fps, units, as_json, check):
    """Show the clips under PATHS (ASF/AMC or BVH files, or folders, searched recursively).

    Per clip: frames, skeleton, degrees of freedom and duration; then totals.
    Every file is fully parsed, so `inspect` also reports damaged input.

    \b
    Examples:
      mcz inspect ../shared/data/cmu
      mcz inspect ../shared/data/cmu/01 --check     what is broken in the source
      mcz inspect ../shared/data/bvh-bandai
    """
    with importing():
        from mocapzip.inputs.inspect import inspect_paths

    report = inspect_paths(paths, asf=asf, fps=fps, check=check, units=units)
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    if check:
        _glitch_lines(report["clips"])
        return
    rows = report["clips"]
    width = max([len(r["path"]) for r in rows] + [4])
    click.echo(f"{'clip':<{width}}  {'frames':>7}  {'dof':>4}  {'fps':>7}  {'seconds':>8}  skeleton")
    for r in rows:
        click.echo(f"{r['path']:<{width}}  {r['frames']:>7}  {r['dof']:>4}  {r['fps']:>7g}  {r['seconds']:>8.2f}  "
                   f"{r['skeleton'] or '-'}")
    t = report["total"]
    click.echo(f"{'total: ' + _count(t['clips'], 'clip'):<{width}}  {t['frames']:>7}  {'':>4}  {'':>7}  "
               f"{t['seconds']:>8.2f}  {_count(t['skeletons'], 'skeleton')}, {t['bytes'] / 1e6:.1f} MB of motion files")


def _glitch_lines(clips: list[dict]) -> None:
    """`inspect --check`: one line per glitch, then how many, in how many clips."""
    from mocapzip.inputs.glitches import Glitch

    found = 0
    for clip in clips:
        for glitch in clip.get("glitches", []):
            click.echo(f"{clip['path']}: {Glitch(**glitch)}")
        found += len(clip.get("glitches", []))
    flagged = sum(1 for clip in clips if clip.get("glitches"))
    unchecked = sum(1 for clip in clips if "glitches" not in clip)
    note = f" ({_count(unchecked, 'clip')} without a skeleton, not checked)" if unchecked else ""
    click.echo(f"{found:,} glitch{'' if found == 1 else 'es'} in {_count(flagged, 'clip')} of {len(clips)}{note}")


def _count(n: int, noun: str) -> str:
    """'1 clip', '2 clips': summaries read as sentences."""
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def _skeletons_line(report: dict) -> str | None:
    """`mcz info`'s skeletons, as each input format describes its own (`InputFormat.described`);
    none when all are ASF skeletons, as before format 8. `info` lists each format's but ASF's."""
    from mocapzip.inputs.registry import input_formats

    listed = [(f, report.get(f"{f.name}_skeletons", [])) for f in input_formats()]
    others = sum(len(skeletons) for f, skeletons in listed if not f.asf_skeletons)
    if not others:
        return None
    parts = []
    for f, skeletons in listed:
        if f.asf_skeletons:  # the rest
            skeletons = [{}] * (report["skeletons"] - others)
        if skeletons:
            parts.append(f.described(skeletons))
    return "skeletons: " + ", ".join(parts)


def _errors(report: dict) -> str:
    """The achieved errors: every clip's MEAN is within -e, so the largest mean is the bound that held."""
    vertex = report.get("largest_max_vertex_error_cm")
    vertex = "" if vertex is None else f", worst vertex {vertex:.3f} cm"
    return (f"largest clip mean error {report['largest_mean_error_cm']:.3f} cm (max {report['largest_max_error_cm']:.3f} cm"
            f"{vertex})")


def _summary_line(s: dict) -> str:
    return (f"{_count(s['clips'], 'clip')}, {_count(s['frames'], 'frame')}: {s['input_bytes']:,} -> "
            f"{s['output_bytes']:,} bytes ({s['input_bytes'] / s['output_bytes']:.1f}x, "
            f"{s['bytes_per_frame']:.2f} bytes/frame), {_errors(s)}, {s['frames'] / s['seconds']:,.0f} frames/s"
            + _repairs(s.get("repaired", [])))


def _repairs(repaired: list) -> str:
    """The summary's note on --repair-glitches: how many ranges, and how far they are from the source."""
    if not repaired:
        return ""
    clips = len({r["path"] for r in repaired})
    return (f"; {_count(len(repaired), 'glitch range')} repaired in {_count(clips, 'clip')}, up to "
            f"{max(r['error_cm'] for r in repaired):.1f} cm from the source (`mcz info` lists them)")


def _named_output(ctx, param, value):
    """Refuse `-o -`: zstd streams to stdout, but an .mcz is an HDF5 file, written by seeking; and
    `-o ''`, which names nothing (a folder's files would go to the current folder)."""
    what = "file" if param.type.file_okay else "folder"
    if value == "-":
        raise click.BadParameter(f"writing to stdout is not supported (an .mcz archive is an HDF5 file); "
                                 f"name a {what}", ctx, param)
    if value == "":
        raise click.BadParameter(f"an empty name names no {what}; name one", ctx, param)
    return value


def _dask_address(ctx, param, value):
    """A malformed --dask (`local:0`, `local:100000`: more workers than this machine can start) is a
    usage error, found before any work."""
    if value is not None:
        try:
            parse_address(value)
        except ClusterError as exc:
            raise click.BadParameter(str(exc).removeprefix("--dask "), ctx, param) from None
    return value


# Options that only tune the lossy codec: given with --lossless they would be silently ignored.
LOSSY_ONLY = ("error_cm", "max_error", "max_vertex_error", "shell_cm", "contact_error", "plant_feet", "repair_glitches", "representation", "transform", "wavelet", "level", "knot_spacing", "split", "segment", "model", "modes")


def _refuse_lossy_options(ctx: click.Context) -> None:
    """Usage error for any lossy-only option given on the command line together with --lossless."""
    given = [p.opts[-1] for p in ctx.command.params
             if p.name in LOSSY_ONLY and ctx.get_parameter_source(p.name) is ParameterSource.COMMANDLINE]
    if given:
        verb = "has" if len(given) == 1 else "have"
        raise click.UsageError(f"{', '.join(given)} {verb} no meaning with --lossless "
                               "(it stores every AMC value exactly); drop one or the other", ctx)


@main.command()
@click.argument("inputs", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), callback=_named_output,
              help="The .mcz archive to write (a file: not stdout, `-o -` is refused).")
@click.option("-e", "--error", "error_cm", type=click.FloatRange(min=0, min_open=True), default=1.0, show_default=True,
              help="Bound on each clip's mean joint-position error in cm, measured end to end.")
@click.option("--max-error", "max_error", metavar="CM|none", callback=max_error_value, default=None,
              help="Also bound every joint of every frame: none ends up further than CM from the source, "
                   "measured end to end through the written AMC (the frames beyond it are patched). Default: "
                   f"{MAX_TO_MEAN:g} x -e, the tightest that costs at most 15 % more bytes (CMU at -e 1: 5.8 % of "
                   "frames patched, 14 % more bytes); tighter bounds cost more (4 cm: 27 %, 3 cm: 63 %; "
                   "docs/fidelity.md); 'none': no bound.")
@click.option("--max-vertex-error", "max_vertex_error", type=click.FloatRange(min=0, min_open=True), metavar="CM",
              help="Also bound every shell vertex of every frame (ACL's error metric: virtual vertices --shell-cm from "
                   "each bone along its axes, in object space; it sees an end bone's twist, which moves no joint): "
                   "none ends up further than CM from the source's (frame patches). Off by default; `mcz info` "
                   "shows each clip's worst vertex either way (docs/fidelity.md).")
@click.option("--shell-cm", "shell_cm", type=click.FloatRange(min=0), default=ACL_SHELL_CM, show_default=True,
              metavar="CM", help="The shell vertices' distance from their bone, as ACL's (0: the joints themselves).")
@click.option("--contact-error", "contact_error", metavar="CM|none", callback=max_error_value, default=None,
              help="Bound on planted feet: each foot or toe joint, in the frames where the source has it on the "
                   "ground and still, ends up within CM of the source (frame patches). Off by default: it costs "
                   "a lot and feet slide MORE, not less (CMU -e 1, 2 cm: +64 % bytes, skate 6.6 -> 11.1 cm/s; "
                   "docs/fidelity.md; --plant-feet keeps them still). 'none': no such bound.")
@click.option("--plant-feet", is_flag=True,
              help="Hold the source's planted feet still: for each run of frames where the source has a foot or "
                   "toe joint on the ground and still, the decoder keeps it at one place, turning the leg to "
                   "reach it (about 4 bytes per stance). CMU at -e 1: skate 6.6 -> 0.4 cm/s for 2.6 % more "
                   "bytes; compress 13 % and decompress 27 % slower (docs/fidelity.md). Not with --segment.")
@click.option("--repair-glitches", is_flag=True,
              help="Let the decoder smooth over glitches in the source (`mcz inspect --check` lists them) instead of "
                   "patching them back: the joints a glitch throws off are the only ones allowed past --max-error "
                   "and --contact-error, and `mcz info` lists each repaired range with its error against the source.")
@click.option("--lossless", is_flag=True,
              help="Every AMC value comes back as written; refuses the lossy-only options "
                   "-e, --max-error, --contact-error, --plant-feet, --repair-glitches, -r, -t, --wavelet, --level, --knot-spacing, "
                   "--split and --segment.")
@click.option("-r", "--representation", type=click.Choice((AUTO_REPRESENTATION, *REPRESENTATIONS)),
              default=AUTO_REPRESENTATION, show_default=True,
              help="What the codec compresses (thesis section 3.2.1). auto: channels where -e times the "
                   f"frame rate (--fps; {DEFAULT_FPS:g} by default) is below {CHANNELS_BELOW_CM_HZ:g} cm/s "
                   f"(-e {CHANNELS_BELOW_CM_HZ / DEFAULT_FPS:g} at {DEFAULT_FPS:g} fps), or --max-vertex-error "
                   f"times it below {CHANNELS_BELOW_VERTEX_CM_HZ:g}; else aligned: the smaller of the two on CMU "
                   "(docs/fidelity.md). The archive stores the one used.")
@click.option("-t", "--transform", type=click.Choice(TRANSFORMS), default="dct-edges", show_default=True,
              help="Temporal transform of the PCA curves: dct-edges (the DCT, with the largest curves' first "
                   "and last frames kept by their ends: clip edges as good as the middle, and the smallest on "
                   "every set measured; docs/fidelity.md), dct (the plain DCT: its error piles up at clip "
                   "edges), dwt (wavelets), poly (polynomials fitted piece by piece, 16 % larger than dct on CMU: "
                   "docs/seed_methods.md) or identity (none).")
@click.option("--wavelet", default="db4", show_default=True, help="PyWavelets wavelet name for --transform dwt.")
@click.option("--level", type=click.IntRange(min=1, max=32), default=None, help="DWT levels (default: as many as the clip allows).")
@click.option("--knot-spacing", type=click.IntRange(min=1, max=512), default=None, metavar="FRAMES",
              help="Frames between the knots of --transform poly, which fits polynomials to each PCA curve piece by "
                   "piece (default 120).")
@click.option("-c", "--classes", default="pooled", show_default=True,
              help="Clips sharing one PCA basis: pooled (one per skeleton, but skeletons with under 4,000 frames "
                   "share one: a basis costs a few KB), subject (one per skeleton), single, FILE.csv (clip path, "
                   "class), or auto[:K]: K classes found from the poses without labels (K chosen by archive size if "
                   "omitted).")
@click.option("--segment", is_flag=True,
              help="Cut long takes at PPCA change points and code each segment on its own (within --error); "
                   "with -c auto the segments of one take can fall in different classes.")
@click.option("--model", type=click.Choice(["pca", "tensor"]), default="pca", show_default=True,
              help="tensor: a class whose clips fill a grid of natural modes (--modes) is also coded as an N-mode "
                   "SVD of its clips warped to one timeline (Kruger et al. 2007), each clip as the model's "
                   "prediction plus what it misses, and keeps whichever takes fewer bytes; `mcz info` says which.")
@click.option("--modes", default=None, metavar="REGEX",
              help="With --model tensor: a pattern searched in each clip's path whose named groups are the "
                   "natural modes, e.g. 'HDM_(?P<actor>[a-z]+)_' or '_(?P<style>[a-z-]+)_(?P<take>[0-9]+)[.]bvh$'. "
                   "A class is a tensor only if every clip matches and they fill the grid.")
@click.option("--split", default=None, metavar="R,P,T",
              help="Force the error split between root motion, PCA and temporal coding (shares of --error).")
@click.option("--asf", type=click.Path(dir_okay=False), help="Skeleton for every AMC (default: the .asf in each AMC's folder; of several different ones, the one whose name begins the AMC's).")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Frame rate of every clip, stored in the archive. By default a clip takes the rate its files "
                   "state (BVH 'Frame Time:'; AMC header '# Frame Rate: 200.000 fps', or 'fps:30' in the ASF's "
                   ":documentation), else 120 (CMU, HDM05: ASF/AMC have no field for it).")
@click.option("--units", type=click.Choice(UNITS), default=None,
              help="Unit of the lengths in BVH files (OFFSETs, position channels). Default: inferred from the "
                   "skeleton's size (a human's in cm, mm or m), refused where it cannot be (--lossless needs none); `mcz info` says which.")
@jobs_option("reading the clips, the error search and the priors")
@click.option("--cache-mb", type=click.IntRange(min=0), default=DEFAULT_CACHE_MB, show_default=True,
              help="Memory (MB) for clips kept between the codec's passes; the others are read again from disk, "
                   "so memory stays bounded however large the database. -c auto and --segment keep every clip "
                   "in memory regardless. With --dask, each worker keeps as much of the class it codes.")
@click.option("--dask", "dask_address", metavar="ADDRESS", default=None, callback=_dask_address,
              help="Run the work as tasks on a Dask cluster instead of -j local workers (pip install "
                   "'mocapzip[dask]'; docs/cluster.md): a scheduler's address (tcp://host:8786), or local:N to "
                   f"start N worker processes here (at most {LOCAL_WORKERS_PER_CORE} per core). The workers read the "
                   "clips themselves, by the paths found here: the data must be on storage they share with this "
                   "machine, at the same paths. This process writes the archive, byte-identical to -j's where "
                   "the workers run the same mcz, numpy and numba as here.")
@click.option("-f", "--force", is_flag=True, help="Overwrite OUTPUT if it exists.")
@click.option("--skip-bad", is_flag=True,
              help="Leave out clips that cannot be read, or that no coding holds within -e and the bounds "
                   "(listed on stderr, in --json and in the archive; the archive is as if they were never given) "
                   "instead of stopping; fails only if no clip is left.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary.")
@click.option("-v", "--verbose", is_flag=True,
              help="Say where the work runs: with --dask, the scheduler, its workers and its dashboard's link.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@reports_errors
def compress(inputs, output, error_cm, max_error, max_vertex_error, shell_cm, contact_error, plant_feet, repair_glitches, lossless, representation, transform, wavelet, level, knot_spacing, classes,
             segment, model, modes, split, asf, fps, units, jobs, cache_mb, dask_address, force, skip_bad, quiet, verbose, as_json):
    """Compress the AMC and BVH clips under INPUTS (folders, searched recursively, or files) into one archive.

    Each AMC pairs with the ASF in its folder (or --asf): copies of one skeleton count as one, and
    of several different ones an AMC takes the one whose name begins its own (07_01.amc: 07.asf).
    A BVH file holds its skeleton; files of one hierarchy share it. Lossy coding keeps a BVH root's
    position channels and every rotation (docs/bvh.md). Inputs are kept; OUTPUT is written
    atomically and never overwritten without -f.

    \b
    Examples:
      mcz compress ../shared/data/cmu -o cmu.mcz                 every clip's mean within 1 cm, every joint 5 cm
      mcz compress ../shared/data/cmu -o cmu.mcz --max-error 3   ... every joint of every frame within 3 cm
      mcz compress ../shared/data/cmu -o cmu.mcz -e 0.5 -c single one basis for all clips
      mcz compress ../shared/data/cmu -o cmu.mcz --lossless --skip-bad  exact AMC values back
                                                                 (a clip cut short is skipped, and listed)
      mcz compress ../shared/data/cmu -o cmu.mcz -c auto --segment  classes (and cuts) found from the poses
      mcz compress ../shared/data/bvh-bandai -o bandai.mcz -e 0.5  BVH files, each written back as BVH
      mcz compress /shared/cmu -o cmu.mcz --dask tcp://sched:8786 -v  on a Dask cluster (docs/cluster.md)
    """
    if lossless:
        _refuse_lossy_options(click.get_current_context())
    with importing():
        from mocapzip import archive
        from mocapzip import progress

    progress.set_quiet(quiet)
    transform_config = {"id": transform}
    if transform == "dwt":
        transform_config.update(wavelet=wavelet, level=level)
    if knot_spacing is not None:
        if transform != "poly":
            raise click.UsageError(f"--knot-spacing is for --transform poly, not {transform}")
        transform_config.update(knot_spacing=knot_spacing)
    bound = None if lossless else max_error_cm(max_error, error_cm)
    contact = None if lossless else contact_error_cm(contact_error)
    settings = archive.Settings(error_cm=error_cm, max_error_cm=bound, contact_error_cm=contact,
                                vertex_error_cm=max_vertex_error, shell_cm=shell_cm,
                                plant_feet=plant_feet, repair_glitches=repair_glitches, representation=representation, transform=transform_config,
                                classes=classes, split=_parse_split(split), fps=DEFAULT_FPS if fps is None else fps,
                                fps_from_files=fps is None, lossless=lossless, segment=segment, model=model,
                                modes=modes)
    context = click.get_current_context()
    if dask_address is not None and context.get_parameter_source("jobs") is ParameterSource.COMMANDLINE:
        raise click.UsageError("-j has no meaning with --dask: the cluster's workers do the work")
    try:
        with _where_work_runs(dask_address, verbose) as cluster:
            summary = archive.compress(inputs, output, settings, asf=asf, force=force,
                                       jobs=cluster.workers if cluster else jobs, skip_bad=skip_bad,
                                       cache_bytes=cache_mb << 20, units=units)
    except archive.SettingsError as exc:  # e.g. --wavelet foo, --fps inf: a usage error, before any work
        raise click.UsageError(str(exc)) from None
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    elif not quiet:
        click.echo(_summary_line(summary), err=True)


def _class_model(row: dict) -> str:
    """--model tensor: what a class took (a tensor of its modes, or PCA where the tensor did not pay
    or its clips fill no grid of --modes)."""
    if row.get("model") == "tensor":
        return ", tensor model over " + " x ".join(f"{m} ({len(v)})" for m, v in zip(row["modes"], row["levels"]))
    if row.get("model") == "pca":
        return ", PCA (no tensor: its clips fill no grid of --modes, or the tensor took more bytes)"
    return ""


@contextmanager
def _where_work_runs(dask_address: str | None, verbose: bool):
    """The Dask cluster the work runs on (`mocapzip.cluster`), or None: local worker processes."""
    if dask_address is None:
        yield None
        return
    from mocapzip.cluster import on_cluster

    with on_cluster(dask_address, dashboard=verbose) as cluster:
        if verbose:
            click.echo(f"mcz: {cluster.describe()}", err=True)
        yield cluster


def _parse_split(text):
    if text is None:
        return None
    try:
        parts = [float(p) for p in text.split(",")]
    except ValueError:
        parts = []
    if len(parts) != 3 or min(parts) < 0 or sum(parts) <= 0:
        raise click.BadParameter("expected three non-negative shares R,P,T, e.g. 0.2,0.4,0.4", param_hint="--split")
    return parts


@main.command()
@click.argument("archive_path", metavar="ARCHIVE", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False), callback=_named_output,
              help="Folder for the ASF/AMC and BVH files (not stdout: `-o -` is refused).")
@click.option("--clip", "patterns", multiple=True, metavar="PATTERN", help="Only clips whose stored path or file name matches (glob, e.g. '09_0*'; repeatable).")
@click.option("-f", "--force", is_flag=True, help="Overwrite existing files.")
@jobs_option("decoding the clips (the files are written in the archive's order)",
             "Threads (worker processes for a lossless archive)")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary.")
@reports_errors
def decompress(archive_path, output, patterns, force, jobs, quiet):
    """Write the ASF/AMC and BVH files of ARCHIVE under OUTPUT at their original relative paths.

    \b
    Examples:
      mcz decompress cmu.mcz -o out/
      mcz decompress cmu.mcz -o out/ --clip '07/*'
    """
    with importing():
        from mocapzip import archive
        from mocapzip import progress

    progress.set_quiet(quiet)
    summary = archive.decompress(archive_path, output, patterns, force=force, jobs=jobs)
    if not quiet:
        click.echo(f"{_count(summary['clips'], 'clip')}, {_count(summary['frames'], 'frame')} -> "
                   f"{_count(summary['files'], 'file')} in {summary['output']}", err=True)


@main.command()
@click.argument("archive_path", metavar="ARCHIVE", type=click.Path(dir_okay=False))
@click.option("--clips/--no-clips", "show_clips", default=True, show_default=True,
              help="List every clip (path, frames, class, mean, p99 and max error, patched frames); --no-clips for totals only.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON (always with every clip).")
@reports_errors
def info(archive_path, show_clips, as_json):
    """Show what ARCHIVE holds: settings, classes, clips, frames, sizes and achieved errors.

    Errors are joint-position errors in cm, measured end to end: a clip's mean (what -e
    bounds), its 99th percentile over all joints and frames (archives of format 5 on), and
    its max (the largest distance of any joint in any frame: what --max-error bounds), and
    (format 13 on) its worst vertex by ACL's metric, shell vertices --shell-cm from every bone
    (what --max-vertex-error bounds). Frames patched to meet a bound are counted per clip.
    """
    with importing():
        from mocapzip import archive

    report = archive.info(archive_path)
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    s = report["settings"]
    bound = f", every joint <= {s['max_error_cm']} cm" if "max_error_cm" in s else ""
    bound += f", every vertex <= {s['vertex_error_cm']} cm" if "vertex_error_cm" in s else ""
    bound += f", planted feet <= {s['contact_error_cm']} cm" if "contact_error_cm" in s else ""
    bound += ", planted feet held" if s.get("plant_feet") else ""
    bound += ", glitches repaired" if s.get("repair_glitches") else ""
    mode = ("lossless" if s["lossless"] else
            f"mean error <= {s['error_cm']} cm{bound}, {s['representation']}, {s['transform']['id']}")
    click.echo(f"{report['path']}: format {report['format_version']}, written by {report['tool']}")
    own = Counter(c["fps"] for c in report["clips"] if c["fps"] != s["fps"])  # rates the clips' files stated
    rates = "".join(f", {_count(n, 'clip')} at {fps:g} fps (from their files)" for fps, n in sorted(own.items()))
    click.echo(f"settings: {mode}, classes {s['classes']}{', segmented' if s.get('segment') else ''}, "
               f"{s['fps']:g} fps{rates}{'' if s.get('fps_from_files', True) else ' (--fps, for every clip)'}")
    click.echo(f"{_count(len(report['clips']), 'clip')}, {_count(report['frames'], 'frame')}, {report['bytes']:,} bytes "
               f"({report['bytes_per_frame']:.2f} bytes/frame), {_errors(report)}")
    click.echo("streams: " + ", ".join(f"{k} {v:,} B" for k, v in sorted(report["stream_bytes"].items())))
    line = _skeletons_line(report)
    if line:
        click.echo(line)
    if report["skipped"]:
        click.echo(f"not in the archive, skipped by compress --skip-bad: {len(report['skipped'])}")
        for skip in report["skipped"]:
            click.echo(f"  {skip['path']}: {skip['error']}")
    dropped = [c for c in report["clips"] if "dropped_frames" in c]
    if dropped:
        click.echo(f"not in the archive, incomplete last frames of truncated inputs: {report['dropped_frames']}")
        for clip in dropped:
            click.echo(f"  {clip['path']}: {clip['dropped_frames']}")
    for c in report["classes"]:
        click.echo(f"  class {c['name']}: {_count(c['clips'], 'clip')}, {_count(c['frames'], 'frame')}, "
                   f"{_count(c['components'], 'component')}{_class_model(c)}")
    for group in report["auto_classes"]:
        tried = {}
        for candidate in group["candidates"]:
            tried[candidate["k"]] = min(candidate["bytes"], tried.get(candidate["k"], candidate["bytes"]))
        units = "clips and segments" if s.get("segment") else "clips"
        click.echo(f"auto classes: K={group['k']} ({group['method']}) for {group['clips']} {units} of pose width "
                   f"{group['width']}; estimated bytes by K: " + ", ".join(f"{k}: {b:,}" for k, b in sorted(tried.items())))
    names = [c["name"] for c in report["classes"]]
    if show_clips:
        _clip_table(report["clips"], names)
    for clip in report["clips"]:
        if "segments" in clip:
            click.echo(f"  {clip['path']}: {_count(len(clip['segments']), 'segment')}: " + ", ".join(
                f"frames {seg['first']}..{seg['first'] + seg['frames'] - 1} {names[seg['class']]}"
                for seg in clip["segments"]))
        if "repaired" in clip:
            click.echo(f"  {clip['path']}: repaired glitches (--repair-glitches), frames and error against the source: "
                       + ", ".join(f"{first}-{last} {cm:g} cm" for first, last, cm in clip["repaired"]))


def _clip_table(clips: list[dict], names: list[str]) -> None:
    """One line per clip; the class is '-' where the archive keeps no class names (lossless)."""
    width = max([len(c["path"]) for c in clips] + [4])
    click.echo(f"{'clip':<{width}}  {'frames':>7}  {'class':<8}  {'mean cm':>8}  {'p99 cm':>8}  {'max cm':>8}  "
               f"{'vertex cm':>9}  {'patched':>7}")
    for c in clips:
        name = names[c["class"]] if c["class"] < len(names) else "-"
        p99 = f"{c['p99_error_cm']:>8.3f}" if "p99_error_cm" in c else f"{'-':>8}"  # not stored before format 5
        vertex = f"{c['max_vertex_error_cm']:>9.3f}" if "max_vertex_error_cm" in c else f"{'-':>9}"  # format 13 on
        click.echo(f"{c['path']:<{width}}  {c['frames']:>7}  {name:<8}  {c['error_cm']:>8.3f}  {p99}  "
                   f"{c['max_error_cm']:>8.3f}  {vertex}  {c.get('patched_frames', 0):>7}")


@main.command("test")
@click.argument("archive_path", metavar="ARCHIVE", type=click.Path(dir_okay=False))
@jobs_option("decoding the clips", "Threads (worker processes for a lossless archive)")
@click.option("--against", type=click.Path(exists=True, file_okay=False), metavar="DIR",
              help="The folder the archive was compressed from: also print each clip's worst vertex by ACL's "
                   "metric against its source file there (docs/fidelity.md), beside its joint errors.")
@click.option("--shell-cm", type=click.FloatRange(min=0), default=ACL_SHELL_CM, show_default=True, metavar="CM",
              help="With --against: the distance of ACL's virtual vertices from every bone.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary.")
@reports_errors
def test_archive(archive_path, jobs, against, shell_cm, quiet):
    """Verify ARCHIVE without writing anything: every checksum, every clip decoded (like zstd -t)."""
    with importing():
        from mocapzip import archive
        from mocapzip import progress

    progress.set_quiet(quiet)
    with archive.Archive(archive_path) as opened:
        opened.verify(jobs)
        count = len(opened.clips)
    if against:
        _shell_table(archive_path, against, shell_cm)
    if not quiet:
        click.echo(f"{archive_path}: OK ({_count(count, 'clip')})", err=True)


def _shell_table(archive_path: str, source_folder: str, shell_cm: float) -> None:
    """One line per clip: the joint errors compress measured and the worst vertex measured now
    against the clip's file under `source_folder`, its bone and frame."""
    with importing():
        import mocapzip
        from mocapzip.progress import progress

    with mocapzip.open(archive_path) as opened:
        missing = [path for path in opened.paths if not os.path.isfile(os.path.join(source_folder, path))]
        if missing:  # before the table: not half of one
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", os.path.join(source_folder, missing[0]))
        width = max([len(path) for path in opened.paths] + [4])
        click.echo(f"{'clip':<{width}}  {'mean cm':>8}  {'p99 cm':>8}  {'max cm':>8}  {'vertex cm':>9}  "
                   f"worst vertex (ACL's metric, {shell_cm:g} cm shell)")
        for clip in progress(opened, desc="vertices", unit="clip", total=len(opened)):
            shell = clip.shell_error(os.path.join(source_folder, clip.path), shell_cm)
            p99 = f"{clip.error.p99_cm:>8.3f}" if clip.error.p99_cm is not None else f"{'-':>8}"
            click.echo(f"{clip.path:<{width}}  {clip.error.mean_cm:>8.3f}  {p99}  {clip.error.max_cm:>8.3f}  "
                       f"{shell.worst:>9.3f}  {shell.worst_bone}, frame {shell.worst_frame}")


@main.command()
@click.argument("inputs", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False), callback=_named_output,
              help="Folder for the converted files, at the inputs' relative paths.")
@click.option("--asf", type=click.Path(dir_okay=False), help="Skeleton for every AMC (default: as compress pairs them).")
@click.option("--units", type=click.Choice(UNITS), default=None,
              help="Unit of the lengths in BVH files (default: inferred from the skeleton's size).")
@click.option("-f", "--force", is_flag=True, help="Overwrite existing files (never an input).")
@click.option("--skip-bad", is_flag=True,
              help="Leave out clips that cannot be converted (listed on stderr) instead of stopping; without it, "
                   "nothing is written unless every clip converts.")
@reports_errors
def convert(inputs, output, asf, units, force, skip_bad):
    """Convert the clips under INPUTS to the other format: each AMC to BVH, each BVH to ASF/AMC.

    Joint positions stay where they were, within 0.01 cm. Every clip is converted before any
    file is written; each file is written whole; inputs are never written over.

    \b
    ASF/AMC to BVH: one joint per ASF bone, at the bone's start, rotated as the bone; the root
    with 6 channels, the others Zrotation Xrotation Yrotation (whatever the bone's dofs; a thigh
    raised 90 degrees sits at this order's gimbal lock, so its angles may jump while the joints
    do not); lengths in cm; the ASF's base pose as rest pose; the clip's frame rate (the AMC
    header's or the ASF's, else 120).
    BVH to ASF/AMC: mcz's model of the hierarchy (docs/bvh.md): bones in cm with identity axes,
    a link bone ("P>child") for each further child of a joint, the root named root, the frame
    rate in the ASF's documentation (fps:30). Refused: an extra root above the hips that moves,
    a joint other than the root whose position channels move. --asf applies to AMC files only.
    Names a format cannot hold (in an ASF/AMC a number, ':' or '#' first, root; in a BVH a brace
    or a keyword) are written escaped with %XX, and an ASF records its joints' BVH names, which a
    conversion back restores (docs/bvh.md, "Names"). A clip whose files mcz would refuse (more
    bones or joints than it takes) is refused.

    \b
    Examples:
      mcz convert ../shared/data/cmu/09 -o bvh/        09_01.amc -> bvh/09_01.bvh, ...
      mcz convert ../shared/data/bvh-bandai -o amc/ --skip-bad
                                                   x.bvh -> amc/x.amc and amc/x.asf (4 clips whose
                                                   extra root moves are left out)
    """
    with importing():
        from mocapzip.convert import convert as convert_clips

    summary = convert_clips(list(inputs), output, asf=asf, units=units, force=force, skip_bad=skip_bad)
    skipped = f" ({_count(len(summary['skipped']), 'clip')} skipped)" if summary["skipped"] else ""
    click.echo(f"{_count(summary['clips'], 'clip')} -> {_count(len(summary['written']), 'file')} in {output}{skipped}",
               err=True)


def _in_place_needs_force(output, force: bool) -> None:
    """An edit without -o replaces ARCHIVE: only when asked to with -f."""
    if output is None and not force:
        raise click.UsageError("name the new archive with -o, or give -f to replace ARCHIVE in place")


def _stored_folder(ctx, param, value):
    if value is not None:
        from mocapzip.archive.edit import stored_folder  # not `importing`: a callback runs before `reports_errors`

        try:
            stored_folder(value)
        except ValueError as exc:
            raise click.BadParameter(str(exc).removeprefix("under "), ctx, param) from None
    return value


EDIT_OUTPUT = click.option("-o", "--output", type=click.Path(dir_okay=False), callback=_named_output,
                           help="The new archive (default: ARCHIVE itself, replaced only with -f).")
EDIT_FORCE = click.option("-f", "--force", is_flag=True, help="Overwrite OUTPUT; without -o, replace ARCHIVE in place.")


@main.command()
@click.argument("archive_path", metavar="ARCHIVE", type=click.Path(dir_okay=False))
@click.argument("patterns", nargs=-1, required=True, metavar="PATTERN...")
@EDIT_OUTPUT
@EDIT_FORCE
@click.option("-q", "--quiet", is_flag=True, help="No summary.")
@reports_errors
def remove(archive_path, patterns, output, force, quiet):
    """Write ARCHIVE without the clips whose stored path or file name matches a PATTERN (glob).

    Every other clip's streams are copied as they are: it decodes to the same bytes and keeps
    its errors. A class or skeleton no clip uses any more goes. The new archive is written
    atomically; ARCHIVE is intact until it is complete. Seconds, where compressing again takes
    minutes (docs/editing.md).

    \b
    Examples:
      mcz remove cmu.mcz '09_*' -o cmu-without-09.mcz
      mcz remove cmu.mcz 07/07_01.amc -f            in place
    """
    _in_place_needs_force(output, force)
    with importing():
        from mocapzip.archive.edit import remove as remove_clips

    summary = remove_clips(archive_path, patterns, output, force=force)
    if not quiet:
        click.echo(f"{_count(len(summary['removed']), 'clip')} removed, {_count(summary['clips'], 'clip')} left -> "
                   f"{summary['output']} ({summary['output_bytes']:,} bytes)", err=True)


@main.command()
@click.argument("archive_path", metavar="ARCHIVE", type=click.Path(dir_okay=False))
@click.argument("inputs", nargs=-1, required=True, type=click.Path())
@EDIT_OUTPUT
@click.option("--under", metavar="FOLDER", callback=_stored_folder, default=None,
              help="Store the new clips under this folder of the archive (e.g. --under 09: 09_01.amc as "
                   "09/09_01.amc; default: relative to each input folder, as compress stores them).")
@click.option("--asf", type=click.Path(dir_okay=False), help="Skeleton for every AMC (default: as compress pairs them).")
@click.option("--units", type=click.Choice(UNITS), default=None,
              help="Unit of the lengths in BVH files (default: inferred from the skeleton's size).")
@jobs_option("reading and coding the new clips")
@click.option("--cache-mb", type=click.IntRange(min=0), default=DEFAULT_CACHE_MB, show_default=True,
              help="Memory (MB) for new clips kept between the codec's passes, as compress's.")
@EDIT_FORCE
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary.")
@reports_errors
def append(archive_path, inputs, output, under, asf, units, jobs, cache_mb, force, quiet):
    """Write ARCHIVE with the AMC and BVH clips under INPUTS added, coded with ARCHIVE's settings.

    The new clips are coded as compress codes them, each in ARCHIVE's class nearest it where
    that takes fewer bytes than a class of their own, and their streams from ARCHIVE's priors; every clip already there is copied as it is. A clip stored under a
    path ARCHIVE holds is refused. The new archive is written atomically; ARCHIVE is intact
    until it is complete. What it costs against compressing everything again: docs/editing.md.

    \b
    Examples:
      mcz append cmu.mcz ../shared/data/cmu/09 --under 09 -o cmu-with-09.mcz
      mcz append cmu.mcz new-takes/ -f               in place
    """
    _in_place_needs_force(output, force)
    with importing():
        from mocapzip.archive.edit import append as append_clips
        from mocapzip import progress

    progress.set_quiet(quiet)
    summary = append_clips(archive_path, list(inputs), output, force=force, jobs=jobs, under=under, asf=asf,
                           units=units, cache_bytes=cache_mb << 20)
    if not quiet:
        click.echo(f"{_count(len(summary['added']), 'clip')} added, {_count(summary['clips'], 'clip')} in all -> "
                   f"{summary['output']} ({summary['output_bytes']:,} bytes)", err=True)


main.add_command(bench)
main.add_command(classify)
main.add_command(plot)
main.add_command(view)

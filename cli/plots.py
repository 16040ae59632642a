"""`mcz plot` and `mcz view`: pictures of an archive's errors and clips (the `plot` extra, matplotlib)."""

from __future__ import annotations

from pathlib import Path

import click

from mocapzip.cli import importing
from mocapzip.cli.errors import reports_errors

PLOT_SUFFIXES = (".png", ".svg")
VIEW_SUFFIXES = (".gif", ".mp4", ".html")


def _suffix(choices: tuple[str, ...]):
    """An -o callback: the suffix names the file's kind, one of `choices`."""
    def check(ctx, param, value):
        if Path(value).suffix.lower() not in choices:
            raise click.BadParameter(f"{value!r}: {ctx.command.name} writes {', '.join(choices[:-1])} or "
                                     f"{choices[-1]} files (the suffix says which)", ctx, param)
        return value
    return check


def _need_matplotlib(command: str) -> None:
    """Before any work: a usage error naming the extra where matplotlib is not installed."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise click.UsageError(f"{command} needs matplotlib: pip install 'mocapzip[plot]'") from None


def _frames(ctx, param, value):
    """--frames A:B, as a Python slice of the clip's frames (either end may be left out)."""
    if value is None:
        return slice(None)
    start, colon, stop = value.partition(":")
    try:
        ends = [int(end) if end.strip() else None for end in (start, stop)]
    except ValueError:
        ends = []
    if not colon or len(ends) != 2:
        raise click.BadParameter(f"{value!r}: expected A:B, frame numbers from 0 (e.g. 0:240, 120:)", ctx, param)
    return slice(*ends)


@click.command()
@click.argument("archive_path", metavar="ARCHIVE", type=click.Path(dir_okay=False))
@click.option("--against", required=True, type=click.Path(exists=True, file_okay=False), metavar="DIR",
              help="The folder the archive was compressed from: each clip is measured against its file there.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), callback=_suffix(PLOT_SUFFIXES),
              help="The picture to write: .png or .svg.")
@click.option("--clip", "pattern", metavar="PATTERN",
              help="Only the clips whose path or file name matches this shell pattern ('09_*', '*walk*').")
@click.option("--kind", type=click.Choice(["time", "joints", "vertex"]), default="time", show_default=True,
              help="time: each frame's mean joint error over time (faint, for one clip or many: its worst joint); joints: each joint's "
                   "mean error and 99th percentile, over every frame; vertex: each frame's worst vertex by ACL's "
                   "metric (docs/acl.md) over time.")
@click.option("-f", "--force", is_flag=True, help="Overwrite the output.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary.")
@reports_errors
def plot(archive_path, against, output, pattern, kind, force, quiet):
    """Draw ARCHIVE's errors against the source files it was compressed from (needs mocapzip[plot]).

    Up to 5 clips share one chart; more are drawn as small multiples (at most 36: narrow --clip),
    except --kind joints, which pools every frame of the clips of one skeleton.

    \b
    Examples:
      mcz plot cmu.mcz --against ../shared/data/cmu --clip '09_0[1-3].amc' -o time.png
      mcz plot cmu.mcz --against ../shared/data/cmu --clip '09_*' --kind joints -o joints.svg
    """
    _need_matplotlib("plot")
    with importing():
        from mocapzip import plots, progress

    progress.set_quiet(quiet)
    drawn = plots.plot(archive_path, against, output, pattern, kind, force)
    if not quiet:
        click.echo(f"{drawn} clip{'' if drawn == 1 else 's'} -> {output}", err=True)


@click.command()
@click.argument("archive_path", metavar="ARCHIVE", type=click.Path(dir_okay=False))
@click.argument("clip")
@click.option("--against", type=click.Path(exists=True, file_okay=False), metavar="DIR",
              help="The folder the archive was compressed from: its file of CLIP is drawn beside the decoded "
                   "one (without it, the decoded one alone).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), callback=_suffix(VIEW_SUFFIXES),
              help="The animation to write: .gif, .mp4 (needs ffmpeg) or .html (one page, nothing loaded from elsewhere).")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True), default=30.0, show_default=True,
              help="Frames per second drawn (the clip's frames subsampled; never more than the clip has).")
@click.option("--frames", "frames", metavar="A:B", callback=_frames, default=None,
              help="The clip's frames to draw, from 0 (default: all, up to --max-frames drawn).")
@click.option("--max-frames", type=click.IntRange(min=1, max=3000), default=300, show_default=True,
              help="Draw at most this many frames (a GIF of the source and the decoded clip takes about 10 KB a frame).")
@click.option("--overlay", is_flag=True, help="The source and the decoded skeleton in one panel, in two colours.")
@click.option("-f", "--force", is_flag=True, help="Overwrite the output.")
@reports_errors
def view(archive_path, clip, against, output, fps, frames, max_frames, overlay, force):
    """Animate CLIP of ARCHIVE (its path or file name) as stick figures beside its source file (needs mocapzip[plot]).

    \b
    Examples:
      mcz view cmu.mcz 09_01.amc --against ../shared/data/cmu -o 09_01.gif
      mcz view cmu.mcz 09_01.amc --against ../shared/data/cmu -o 09_01.html --overlay
    """
    _need_matplotlib("view")
    if output.lower().endswith(".mp4"):
        with importing():
            from mocapzip.plots import ffmpeg_available
        if not ffmpeg_available():
            raise click.UsageError("an .mp4 needs ffmpeg, which is not on PATH: install it, or write .gif or .html")
    with importing():
        from mocapzip import plots

    drawn, available = plots.view(archive_path, clip, output, against, fps, frames, max_frames, overlay, force)
    click.echo(f"{drawn} frames drawn of {available} -> {output}", err=True)

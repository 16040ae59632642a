"""The `mcz` command line: click front end over the mocapzip pipeline.

Conventions follow zstd: `-o` names the output, inputs are kept, nothing is
overwritten without `-f`, and exit codes are 0 (success), 1 (bad input, damaged
archive, I/O failure: one line on stderr, never a traceback) and 2 (usage).
"""

from __future__ import annotations

import functools
import json
import sys
import warnings

import click

from .. import __version__
from ..formats.errors import MocapFormatError


def _fail(message: str) -> None:
    click.echo(f"mcz: error: {message}", err=True)
    sys.exit(1)


def reports_errors(command):
    """Turn expected failures into one line on stderr and exit code 1."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("always")
                warnings.showwarning = lambda message, *a, **k: click.echo(f"mcz: warning: {message}", err=True)
                return command(*args, **kwargs)
        except MocapFormatError as exc:
            _fail(str(exc))
        except FileExistsError as exc:
            _fail(f"{exc.filename or exc}: already exists (use -f/--force to overwrite)")
        except OSError as exc:
            _fail(f"{exc.filename}: {exc.strerror}" if exc.filename else str(exc))
        except KeyboardInterrupt:
            _fail("interrupted; no output was left behind")

    return wrapper


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "-V", "--version", prog_name="mcz")
def main():
    """mcz: compress motion-capture databases (Acclaim ASF/AMC) into one .mcz archive.

    \b
    Typical use:
      mcz inspect ../shared/data/cmu            what is there: clips, frames, skeletons
      mcz compress ../shared/data/cmu -o db.mcz one archive, every clip within 1 cm
      mcz decompress db.mcz -o out/             the ASF and AMC files back

    Run `mcz COMMAND --help` for the options of each command.
    """


@main.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path())
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), help="Skeleton for every AMC (default: the one .asf in each AMC's folder).")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True), default=120.0, show_default=True, help="Frame rate for durations (ASF/AMC do not store it).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@reports_errors
def inspect(paths, asf, fps, as_json):
    """Show the clips under PATHS (ASF/AMC files or folders, searched recursively).

    Per clip: frames, skeleton, degrees of freedom and duration; then totals.
    Every file is fully parsed, so `inspect` also reports damaged input.
    """
    from ..inspect import inspect_paths

    report = inspect_paths(paths, asf=asf, fps=fps)
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    rows = report["clips"]
    width = max([len(r["path"]) for r in rows] + [4])
    click.echo(f"{'clip':<{width}}  {'frames':>7}  {'dof':>4}  {'seconds':>8}  skeleton")
    for r in rows:
        click.echo(f"{r['path']:<{width}}  {r['frames']:>7}  {r['dof']:>4}  {r['seconds']:>8.2f}  {r['skeleton'] or '-'}")
    t = report["total"]
    click.echo(f"{'total: ' + str(t['clips']) + ' clips':<{width}}  {t['frames']:>7}  {'':>4}  {t['seconds']:>8.2f}  "
               f"{t['skeletons']} skeletons, {t['bytes'] / 1e6:.1f} MB of AMC")

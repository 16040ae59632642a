"""How every `mcz` command fails: one line on stderr and exit code 1, never a traceback."""

from __future__ import annotations

import functools
import sys
import warnings

import click

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

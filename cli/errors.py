"""How every `mcz` command fails: one line on stderr, never a traceback; exit code 1 for bad input
(`reports_errors`), 2 for a usage error (`UsageInOneLine`)."""

from __future__ import annotations

import functools
import gc
import os
import select
import signal
import sys
import threading
import warnings
from contextlib import contextmanager
from concurrent.futures.process import BrokenProcessPool

import click

from mocapzip.cluster import ClusterError
from mocapzip.formats.errors import MocapFormatError


def _one_line(message: str) -> str:
    """The message in one line, whatever it holds: a name from a file may carry line breaks."""
    return message.encode("unicode_escape", "backslashreplace").decode("ascii") if not message.isprintable() else message


def _fail(message: str) -> None:
    click.echo(f"mcz: error: {_one_line(message)}", err=True)
    sys.exit(1)


class _UsageLine(click.UsageError):
    """A usage error shown in one line, naming the command and its help, instead of click's usage,
    hint and message in three or four: `mcz compress: Missing option '-o' / '--output' (see mcz
    compress --help)`."""

    def __init__(self, message: str, command: str):
        super().__init__(message)
        self.command = command

    def show(self, file=None) -> None:
        message = _one_line(self.format_message().removesuffix("."))
        click.echo(f"{self.command}: {message} (see {self.command} --help)", err=True)


class UsageInOneLine(click.Group):
    """The `mcz` group: every usage error, exit code 2, as one line (`_UsageLine`). Those of the
    group itself (an unknown option or command) arise while its context is made or it resolves the
    command; a command's own (a missing or bad option or argument, a UsageError it raises) while it
    invokes the command. `mcz` alone still prints the help. The program is named by the group's
    name, also where it runs as `python -c` (click would call it `-c`)."""

    def main(self, args=None, prog_name=None, **extra):
        return super().main(args, prog_name or self.name, **extra)

    def make_context(self, info_name, args, parent=None, **extra):
        with _usage_in_one_line(lambda: info_name):
            return super().make_context(info_name, args, parent, **extra)

    def invoke(self, ctx):
        # click leaves some errors without their context (`-e` as the last word: "Option '-e'
        # requires an argument"): the command they belong to is the one being invoked.
        with _usage_in_one_line(lambda: " ".join(filter(None, [ctx.command_path, ctx.invoked_subcommand]))):
            return super().invoke(ctx)


@contextmanager
def _usage_in_one_line(command_path):
    """Usage errors raised inside as `_UsageLine`s, naming their context's command, else `command_path()`."""
    try:
        yield
    except click.exceptions.NoArgsIsHelpError:
        raise
    except click.UsageError as exc:
        raise _UsageLine(exc.format_message(), exc.ctx.command_path if exc.ctx else command_path()) from None


def _stdout_reader_gone() -> bool:
    """Whether stdout is a pipe whose reader has gone (`mcz info | head`): poll reports an error
    (or a hang-up) on it. A broken pipe elsewhere (a child process's stdin, a FIFO given as a
    file) is an error like any other."""
    try:
        descriptor = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # no stdout (`>&-`), or not a file (click's test runner)
        return False
    if not hasattr(select, "poll"):
        return False
    poller = select.poll()
    poller.register(descriptor, select.POLLOUT)
    return any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))


def _stop_quietly() -> None:
    """Stdout's reader has gone: stop as cat does, with exit code 1 and no message. Stdout then
    points at /dev/null, so that Python's own flush at exit does not fail again."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    sys.exit(1)


def _terminate(signum, frame):
    raise KeyboardInterrupt("SIGTERM")


def _interruption(exc: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (Ctrl-C, or SIGTERM: `_terminate`) among the causes of `exc`, if any:
    one that arrives while numba's compiled code allocates comes out of its dispatcher as a
    SystemError ("... returned a result with an exception set") that it caused."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def reports_errors(command):
    """Turn expected failures into one line on stderr and exit code 1.

    SIGTERM is handled like Ctrl-C (KeyboardInterrupt), so both unwind through the same
    clean-up: writers remove their temporary files and no partial output is left. What the
    command's imports froze (`importing`) is unfrozen when it ends, unless something was frozen
    before it: a caller in the same process keeps its collector as it was.
    """

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        main_thread = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
        frozen = gc.get_freeze_count()  # before the command's `importing` freezes its imports
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("always")
                warnings.showwarning = lambda message, *a, **k: click.echo(f"mcz: warning: {message}", err=True)
                result = command(*args, **kwargs)
                if sys.stdout is not None:  # None when run with stdout closed (`>&-`)
                    sys.stdout.flush()  # a reader gone (`| head`) is found here, not in Python's flush at exit
                return result
        except MocapFormatError as exc:
            _fail(str(exc))
        except FileExistsError as exc:
            _fail(f"{exc.filename or exc}: already exists (use -f/--force to overwrite)")
        except OSError as exc:
            if isinstance(exc, BrokenPipeError) and _stdout_reader_gone():
                _stop_quietly()
            _fail(f"{exc.filename}: {exc.strerror}" if exc.filename else str(exc))
        except ClusterError as exc:
            _fail(f"{exc}; no partial file was left behind")
        except MemoryError:  # numpy's and numba's (a limit on address space, or a full machine)
            _fail("out of memory; no partial file was left behind")
        except BrokenProcessPool:  # a worker killed (the OOM killer, kill -9): its parent ends cleanly
            _fail("a worker process ended abruptly (killed, or out of memory); no partial file was left behind")
        except (KeyboardInterrupt, SystemError) as exc:
            interruption = _interruption(exc)
            if interruption is None:  # a SystemError of its own: a fault of mcz, its traceback shown
                raise
            _fail(f"interrupted ({interruption.args[0] if interruption.args else 'SIGINT'}); "
                  "no partial file was left behind")
        finally:
            if not frozen:
                gc.unfreeze()  # what `importing` froze: only the exit's collection is spared it (cli/__init__.py)
            if main_thread:
                signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)

    return wrapper

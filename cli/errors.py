"""How every `mcz` command fails: one line on stderr and exit code 1, never a traceback."""

from __future__ import annotations

import functools
import gc
import os
import select
import signal
import sys
import threading
import warnings
from concurrent.futures.process import BrokenProcessPool

import click

from mocapzip.cluster import ClusterError
from mocapzip.formats.errors import MocapFormatError


def _fail(message: str) -> None:
    """One line, whatever the message holds: a name from a file may carry line breaks."""
    one_line = message.encode("unicode_escape", "backslashreplace").decode("ascii") if not message.isprintable() else message
    click.echo(f"mcz: error: {one_line}", err=True)
    sys.exit(1)


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

"""One progress channel for every long run (root helper): fit, fit_shared, sweep, the
stabilization survey, batches and the bootstrap all take ``progress`` and mean the same by it.

- ``progress=False`` (or None): nothing.
- ``progress=True``: a bar on a terminal (tqdm, one tick per record, the latest record's
  summary beside it). When standard error is not a terminal (a log file, a pipe, CI, a
  notebook) a run stays silent for its first ``HEARTBEAT`` seconds, then writes the latest
  record's line, with the time elapsed, at most once per ``HEARTBEAT`` seconds: a short run
  prints nothing, a long one shows it is alive.
- ``progress="lines"``: one line per record on standard error, terminal or not (what the
  command line's ``--progress`` asks for when its output goes to a file).
- ``progress=callable``: receives every record (a StageRecord, a SweepRow, ...); its return
  value is ignored.
"""

import contextlib
import numbers
import sys
import time

from .errors import OptionError

__all__ = ["check_progress", "channel", "MODES"]

#: The string values ``progress`` takes besides True, False, None and a callable.
MODES = ("lines",)

#: Seconds between two lines of ``progress=True`` when standard error is not a terminal.
HEARTBEAT = 30.0


def check_progress(progress, what="each record"):
    """``progress`` normalised to False, True, "lines" or the callable; OptionError otherwise.

    The integers 0 and 1 and numpy booleans count as False and True.
    """
    if progress is None:
        return False
    if callable(progress):
        return progress
    if isinstance(progress, str):
        if progress in MODES:
            return progress
    elif isinstance(progress, bool) or type(progress).__name__ == "bool_" or (
            isinstance(progress, numbers.Integral) and progress in (0, 1)):
        return bool(progress)
    raise OptionError(f"progress must be True, False, 'lines' or a callable taking {what}, "
                      f"got {progress!r}; pass progress=True for a bar on a terminal")


@contextlib.contextmanager
def channel(progress, describe, *, total=None, unit="stage", what="each record"):
    """Context manager yielding ``emit(record)`` for the normalised ``progress``.

    Parameters
    ----------
    progress : bool, str, callable or None
        See the module docstring.
    describe : callable
        ``describe(record) -> str``, one line of text per record (no newline).
    total : int, optional
        The number of records expected, for the bar (unknown: a counter).
    unit : str, optional
        What one record is, for the bar ("stage", "order", "file", ...).
    what : str, optional
        What the callable receives, for the error message.
    """
    progress = check_progress(progress, what)
    if callable(progress):
        yield progress
        return
    if progress == "lines":
        def write(record):
            sys.stderr.write(describe(record) + "\n")
            sys.stderr.flush()
        yield write
        return
    if not progress:
        yield _ignore
        return
    if not _is_terminal(sys.stderr):
        yield _heartbeat(describe)
        return
    from tqdm import tqdm

    class _Bar(tqdm):
        # no monitor thread (it adjusts the redraw rate of slow loops; every record is drawn
        # here): a fit with n_jobs forks its workers only when no other thread runs
        monitor_interval = 0

    bar = _Bar(total=total, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True)
    try:
        def tick(record):
            # every record is drawn (tqdm otherwise redraws at most every 0.1 s, and a fit
            # whose records all came within that showed none before the bar closed)
            bar.update(1)
            bar.set_postfix_str(describe(record), refresh=True)
        yield tick
    finally:
        bar.close()


def _ignore(record):
    return None


def _heartbeat(describe):
    """``emit(record)`` writing the record's line, after the time elapsed, when at least
    ``HEARTBEAT`` seconds have passed since the run began or since the last line."""
    start = last = time.monotonic()

    def beat(record):
        nonlocal last
        now = time.monotonic()
        if now - last < HEARTBEAT:
            return
        last = now
        sys.stderr.write(f"[{_elapsed(now - start)}] {describe(record)}\n")
        sys.stderr.flush()
    return beat


def _elapsed(seconds):
    """``"45 s"``, ``"3 min 05 s"``, ``"1 h 02 min"``."""
    seconds = int(seconds)
    if seconds < 60:
        return f"{seconds} s"
    minutes, seconds = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {seconds:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


def _is_terminal(stream):
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False

"""Atomic file output (layer L0): write to a temporary file beside the target, then
``os.replace`` it, so an interrupted run never leaves a partial file; and the escaping of
user-supplied strings (file names, data names, headers) in Markdown and CSV output."""

import errno
import os
import sys
import tempfile
import warnings

__all__ = ["atomic_write_text", "atomic_write_bytes", "md_text", "md_cell", "csv_row",
           "one_line", "run_holding_warnings", "printable_streams"]


def atomic_write_bytes(path, payload):
    """Write ``payload`` (bytes) to ``path`` atomically."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):         # before a temporary file is made in its parent folder
        raise IsADirectoryError(errno.EISDIR, "is a folder; give a file name inside it",
                                path)
    if not os.path.isdir(folder):
        raise FileNotFoundError(errno.ENOENT, "its folder does not exist", path)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
        os.chmod(tmp, 0o666 & ~_umask())        # mkstemp makes 0600; use the usual mode
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def atomic_write_text(path, text):
    """Write ``text`` (UTF-8) to ``path`` atomically; characters UTF-8 cannot encode (lone
    surrogates from undecodable file names) are written as backslash escapes."""
    atomic_write_bytes(path, text.encode("utf-8", "backslashreplace"))


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def one_line(text):
    """``text`` on one line: whitespace runs (line breaks included) become one space and
    other non-printable characters are dropped (for names echoed to the terminal)."""
    return "".join(c for c in " ".join(str(text).split()) if c.isprintable())


def md_text(text):
    """``text`` as one line of inline Markdown that cannot start a new block.

    Every run of whitespace (newlines, carriage returns, Unicode line and paragraph
    separators, tabs) becomes one space, other control characters are dropped, and ``<``
    becomes ``&lt;`` (no HTML comment or tag can hide the rest of the file).
    """
    return one_line(text).replace("<", "&lt;")


def md_cell(value):
    """A Markdown table cell: :func:`md_text` with ``|`` escaped."""
    return md_text(value).replace("|", "\\|")


def csv_row(values):
    """One CSV line (no line terminator), RFC 4180: a cell holding a comma, a quote, any line
    break (``\\r``, ``\\n``, Unicode separators) or other control character is quoted, so it
    stays one cell; ``None`` is an empty cell."""
    return ",".join(_csv_cell("" if v is None else str(v)) for v in values)


def _csv_cell(text):
    if any(c in ',"' or (not c.isprintable() and c != " ") for c in text):
        return '"' + text.replace('"', '""') + '"'
    return text


def run_holding_warnings(run, *args):
    """``run(*args)`` with its warnings held back: after it returns they are written to
    stderr as ``warning: <message>`` lines (one per distinct message); if it raises they are
    dropped, so an ``error:`` line printed by the caller is the only text on stderr."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        result = run(*args)
    for text in dict.fromkeys(one_line(w.message) for w in caught):
        sys.stderr.write(f"warning: {text}\n")
    return result


def printable_streams():
    """Let stdout and stderr write any str (lone surrogates of undecodable file names become
    backslash escapes instead of raising UnicodeEncodeError). A standard stream the process
    was started without (``>&-``, ``2>&-``) is opened on the null device first: else the
    first file opened would get its descriptor (and IPOPT's or Python's output with it) and
    ``sys.stdout`` would be None."""
    for fd, name in ((1, "stdout"), (2, "stderr")):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_WRONLY)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
            setattr(sys, name, open(fd, "w", encoding="utf-8", closefd=False))
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.reconfigure(errors="backslashreplace")
        except (AttributeError, ValueError, OSError):
            pass

"""The ``freqid`` command line's dispatcher (layer 10).

Commands (one module of :mod:`freqid_casadi.cli` each, listed in :data:`COMMANDS`)::

    freqid example {A,B,C,fractional} [--sections N] [--method M] [--out DIR] [--force]
    freqid fit FILE --sections N [--integrator [K|auto]] [--no-delay] [--basis B] [--method M]
                    [--gain-sign S] [--zeros Z] [--tol X] [--final-max-iter N] --out DIR
                    [--force]
    freqid reproduce [--examples LIST] [--quick] [--out DIR]    (studies.reproduce_report)
    freqid sweep FILE|example:X --orders SPEC [--target X] --out DIR
    freqid ablation [--examples LIST] [--quick] [--out DIR]     (studies.ablation)
    freqid frf ..., freqid batch ..., freqid modal ...

Each command parses its arguments, calls the API (:func:`freqid_casadi.fitting.fit.fit`), writes a
report folder (:func:`freqid_casadi.report.folder.write_fit_report`) and prints a short summary.
Progress goes to stderr: a bar when stderr is a terminal, elsewhere a line per 30 s of a
long run; ``--progress`` writes one line per stage, ``--quiet`` silences it.

Errors: a :class:`~freqid_casadi.errors.FreqidError`, an ``OSError`` while writing, or a
usage error prints one line ``error: <message>`` to stderr and returns 2;
KeyboardInterrupt prints ``error: interrupted`` and returns 130. No traceback is shown for
either, and no partial report is left behind.

This module only builds the parser from :data:`COMMANDS`, dispatches and handles the errors
(:func:`main`); how to add a command: :mod:`freqid_casadi.cli`. ``app.fit`` is the fit the
``example`` and ``fit`` commands call (one name, so a test can replace it).
"""

import argparse
import shlex
import sys

from .. import _interrupt, _textio
from ..report import outputs as _outputs
from .common import error_line as _error, os_exit as _os_exit
from ..errors import FreqidError
from ..fitting.fit import fit  # noqa: F401  (called as app.fit by the example and fit commands)
from ..systems.examples import EXAMPLES, FRACTIONAL_SECTIONS

__all__ = ["main", "build_parser", "EXAMPLES", "FRACTIONAL_SECTIONS", "PROG"]

PROG = "freqid"


class _UsageError(Exception):
    """A command-line usage error (reported as one ``error:`` line, exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse parser whose errors are one ``error: ...`` line, not usage + message."""

    def error(self, message):
        raise _UsageError(f"{message} (see '{self.prog} --help')")


# ----------------------------------------------------------------------------- commands


def _plugin(module_name):
    """(add, run) of the command module ``module_name`` of this package (its ``add_cli``
    and ``run_cli``), which is imported only when that command runs or the parser is
    built."""
    import importlib

    def add(sub):
        mod = importlib.import_module(f"{__package__}.{module_name}")
        before = set(sub.choices)
        mod.add_cli(sub)
        (name,) = set(sub.choices) - before
        return sub.choices[name]

    def run(args, command):
        mod = importlib.import_module(f"{__package__}.{module_name}")
        return mod.run_cli(args, command)

    return add, run


#: name -> (add parser, run command): every ``freqid`` command, in the order of ``--help``;
#: each is the module of this package of the same name (its ``add_cli`` and ``run_cli``).
COMMANDS = {name: _plugin(name) for name in ("example", "fit", "reproduce", "sweep",
                                             "ablation", "frf", "batch", "modal")}


def build_parser():
    """The argparse parser of the ``freqid`` command (one subparser per command)."""
    parser = _Parser(prog=PROG, description="Stable, minimum-phase low-order models with "
                                            "delay from frequency-response data.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True,
                                parser_class=_Parser)
    for name, (add, _) in COMMANDS.items():
        add(sub).set_defaults(_run=name)
    return parser


# ----------------------------------------------------------------------------- main


def main(argv=None):
    """Run the ``freqid`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 on a usage, data or option error, 130 when interrupted by Ctrl-C,
        143 by SIGTERM.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    command = " ".join([PROG] + [shlex.quote(a) for a in argv])
    _textio.printable_streams()                          # undecodable file names stay printable
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:                    # --help, --version
            return exc.code if isinstance(exc.code, int) else 0
        inputs = [getattr(args, a, None) for a in ("file", "folder", "records")]
        with _interrupt.handlers(), _outputs.inputs(_outputs.input_paths(inputs)):
            return _textio.run_holding_warnings(COMMANDS[args._run][1], args, command)
    except _UsageError as exc:
        _error(exc)
        return 2
    except FreqidError as exc:
        _error(exc)
        return 2
    except OSError as exc:
        return _os_exit(exc)
    except KeyboardInterrupt as exc:
        _error("interrupted")
        return _interrupt.exit_status(exc)
    except (MemoryError, RecursionError, ArithmeticError, ValueError, TypeError) as exc:
        _error(f"internal error ({type(exc).__name__}: {exc}); please report it with the "
               "command line")
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

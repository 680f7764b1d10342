"""The ``freqid`` command line (layer 10).

:mod:`.app` builds the parser from its table :data:`~freqid_casadi.cli.app.COMMANDS`,
dispatches and turns errors into one ``error:`` line and an exit code; every command is one
module of this package: :mod:`.example`, :mod:`.fit`, :mod:`.reproduce`, :mod:`.sweep`,
:mod:`.ablation`, :mod:`.frf`, :mod:`.batch`, :mod:`.modal`. What several commands share
(argument types, the fit's option groups, data-file options, output lines) is in
:mod:`.common`.

How to add a command: write a module ``cli/<name>.py`` with two functions,
``add_cli(subparsers)``, which adds the ``<name>`` subparser (``subparsers.add_parser``,
with its ``help`` and ``description``) and returns it, and ``run_cli(args, command)``,
which runs it with the parsed ``args`` (``command`` is the quoted command line, the first
line of a report) and returns the exit code; then add ``"<name>"`` to the table in
:data:`~freqid_casadi.cli.app.COMMANDS` (its place there is its place in ``freqid --help``).
The module is imported only when the parser is built. Raise a
:class:`~freqid_casadi.errors.FreqidError` for bad input; :func:`~freqid_casadi.cli.app.main`
prints it as ``error: <message>`` and returns 2 (Ctrl-C: 130), so a command never prints a
traceback. Test it through ``main([...])`` (tests/test_cli.py).
"""

from .app import main

__all__ = ["main"]

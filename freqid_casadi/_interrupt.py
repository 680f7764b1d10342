"""Ctrl-C and SIGTERM during a fit (layer L0).

CasADi runs IPOPT in C++ and calls back into Python for the objective's derivatives; a
``KeyboardInterrupt`` raised inside such a callback is caught by CasADi and IPOPT carries on.
So while a solver runs (:func:`guard`) SIGINT and SIGTERM only set a flag; IPOPT's
iteration callback (:func:`ipopt_callback`, nlpsol option ``"iteration_callback"``) returns
nonzero when the flag is set, IPOPT stops after the current iteration, and :func:`guard`
raises :class:`Interrupted` (a ``KeyboardInterrupt``) as the solver returns. Outside a
solver the handler raises at once. The barrier-LM loop calls :func:`check` every iteration.

The command line installs the handler for the whole command (:func:`handlers`), so SIGTERM
is handled too (exit status 143; Ctrl-C 130); an API call of ``fit`` gets the SIGINT
handler only while a solver runs, and only if the process has Python's default one.
"""

import contextlib
import signal
import threading

import numpy as np

__all__ = ["Interrupted", "handlers", "guard", "check", "requested", "construct",
           "ipopt_callback",
           "exit_status"]

_STATE = {"signum": None, "depth": 0}
_CALLBACKS = {}          # (n_x, n_g, n_p) -> casadi.Callback (kept alive with the process)


class Interrupted(KeyboardInterrupt):
    """A fit stopped by SIGINT (Ctrl-C) or SIGTERM; ``signum`` says which."""

    def __init__(self, signum=signal.SIGINT):
        super().__init__("interrupted")
        self.signum = int(signum)


def exit_status(exc):
    """Exit status of a command stopped by ``exc``: 128 + the signal number (130 for
    Ctrl-C, 143 for SIGTERM)."""
    return 128 + int(getattr(exc, "signum", signal.SIGINT))


def requested():
    """True if SIGINT or SIGTERM arrived and has not been raised yet."""
    return _STATE["signum"] is not None


def check():
    """Raise :class:`Interrupted` if a signal arrived (and clear the flag)."""
    signum = _STATE["signum"]
    if signum is not None:
        _STATE["signum"] = None
        raise Interrupted(signum)


def _handle(signum, frame):
    _STATE["signum"] = signum
    if _STATE["depth"] == 0:
        check()


def _main_thread():
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def handlers():
    """While the block runs, SIGINT and SIGTERM (and SIGHUP, if it has its default action:
    the terminal closed; exit status 129) raise :class:`Interrupted` (or, inside
    :func:`guard`, stop the solver first). Previous handlers are restored afterwards."""
    if not _main_thread():
        yield
        return
    sigs = [signal.SIGINT, signal.SIGTERM]
    hup = getattr(signal, "SIGHUP", None)     # a closed terminal; not under nohup (SIG_IGN)
    if hup is not None and signal.getsignal(hup) is signal.SIG_DFL:
        sigs.append(hup)
    old = {s: signal.getsignal(s) for s in sigs}
    for s in old:
        signal.signal(s, _handle)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@contextlib.contextmanager
def guard():
    """Run a solver: signals only set the flag; on leaving, raise :class:`Interrupted` if
    one arrived. Installs the SIGINT handler for the block if Python's default is active."""
    own = _main_thread() and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    if own:
        signal.signal(signal.SIGINT, _handle)
    _STATE["depth"] += 1
    try:
        yield
    finally:
        _STATE["depth"] -= 1
        if own:
            signal.signal(signal.SIGINT, signal.default_int_handler)
    if _STATE["depth"] == 0:
        check()


def construct(callback, name):
    """``callback.construct(name, {})`` with signals deferred (:func:`guard`).

    CasADi calls the callback's Python methods while it constructs it (and while it builds
    a solver around it); a KeyboardInterrupt raised in one of them is caught there and
    comes out as a RuntimeError, or is lost (measured: 3 of 25 Ctrl-C's sent at random
    times during a fit of example C did not stop it). Deferred, it is raised as
    :class:`Interrupted` when the construction is done.

    Parameters
    ----------
    callback : casadi.Callback
    name : str
    """
    with guard():
        callback.construct(name, {})


def ipopt_callback(nlp):
    """nlpsol options that stop IPOPT after the current iteration once a signal arrived.

    Parameters
    ----------
    nlp : dict
        The NLP given to ``casadi.nlpsol`` (``"x"``, optional ``"g"`` and ``"p"``).

    Returns
    -------
    dict
        ``{"iteration_callback": cb}`` with a cached ``casadi.Callback`` whose output is 1
        when :func:`requested`, else 0.
    """
    import casadi as ca

    def size(key):
        v = nlp.get(key)
        return 0 if v is None else int(v.numel())

    key = (size("x"), size("g"), size("p"))
    if key not in _CALLBACKS:
        _CALLBACKS[key] = _make_callback(ca, *key)
    return {"iteration_callback": _CALLBACKS[key]}


def stop_callback(n_x, n_g, check, name="iteration_monitor"):
    """A new ``iteration_callback`` for an NLP without parameters that stops IPOPT when a
    signal arrived or when ``check(x)`` is true after an iteration.

    Parameters
    ----------
    n_x, n_g : int
        Numbers of variables and constraints of the NLP.
    check : callable
        ``check(x) -> bool`` on the iterate, ndarray of float, shape (n_x,).
    name : str
        Name of the CasADi Function.

    Returns
    -------
    casadi.Callback
    """
    import casadi as ca

    return _make_callback(ca, n_x, n_g, 0, check, name)


def _make_callback(ca, n_x, n_g, n_p, check=None, name=None):
    # one class for all callbacks (a class made per call is cyclic garbage that kept the
    # check's closure, a stage's whole problem, alive until the next collection)
    return _stop_class(ca)((n_x, 1, n_g, n_x, n_g, n_p), check,
                           name or f"freqid_interrupt_{n_x}_{n_g}_{n_p}")


_STOP_CLASS = []


def _stop_class(ca):
    """The ``casadi.Callback`` subclass of :func:`stop_callback` (built on first use)."""
    if _STOP_CLASS:
        return _STOP_CLASS[0]

    class _Stop(ca.Callback):
        def __init__(self, sizes, check, name):
            ca.Callback.__init__(self)
            # nlpsol outputs: x, f, g, lam_x, lam_g, lam_p
            self.sizes, self.check = sizes, check
            construct(self, name)

        def get_n_in(self):
            return ca.nlpsol_n_out()

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ca.nlpsol_out(i)

        def get_name_out(self, i):
            return "stop"

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(self.sizes[i], 1)

        def eval(self, arg):
            if requested():                     # a signal: guard() raises after the stop
                return [1]
            if self.check is None:
                return [0]
            return [1 if self.check(np.array(arg[0].full(), float).reshape(-1)) else 0]

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            # copy-free: CasADi's own buffers, not six DM arguments built per iteration
            # (the iterate x is copied: the check may keep it)
            stop = requested() or (self.check is not None and bool(self.check(
                np.frombuffer(arg[0], dtype=np.float64).copy())))
            if res[0] is not None:
                np.frombuffer(res[0], dtype=np.float64)[0] = 1.0 if stop else 0.0
            return 0

    _STOP_CLASS.append(_Stop)
    return _Stop

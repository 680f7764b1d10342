"""The machine and libraries a result was computed with (layer 8).

Two machines can give a fit different last digits, and on a badly conditioned problem more
than that (docs/guide/reproducibility.md): the BLAS kernel OpenBLAS picks for the CPU and
the SIMD level numpy dispatches its ``exp``, ``sin``, ``cos`` and complex arithmetic to are
chosen at run time, per machine. Every report states them, so that two reports that
differ can be told apart by where they were made.
"""

import importlib.metadata
import os
import platform

import numpy as np

__all__ = ["environment", "environment_line", "computed_on", "computed_on_lines"]


def _version(dist):
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def _cpu():
    """The CPU's model name (Linux: /proc/cpuinfo), else what ``platform`` says."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _numpy_simd():
    """The target numpy dispatched ``exp`` on float64 to (e.g. "X86_V3"), None if unknown."""
    try:
        from numpy.lib.introspect import opt_func_info
    except ImportError:                       # numpy < 2.0
        return None
    try:
        info = opt_func_info(func_name="^exp$", signature="float64")
        return str(info["exp"]["dd"]["current"])
    except (KeyError, TypeError, ValueError):
        return None


def _blas():
    """One dict per BLAS library loaded (numpy's, scipy's): its api, version, kernel."""
    try:
        import scipy.linalg  # noqa: F401  (load scipy's BLAS too)
        from threadpoolctl import threadpool_info
    except ImportError:
        return []
    return [{"library": i.get("internal_api"), "version": i.get("version"),
             "kernel": i.get("architecture"), "prefix": i.get("prefix")}
            for i in threadpool_info() if i.get("user_api") == "blas"]


def environment():
    """Where a result is being computed: the versions and run-time numerical paths that
    can move its last digits.

    Returns
    -------
    dict
        ``freqid_casadi``, ``python``, ``numpy``, ``scipy``, ``casadi``, ``control``
        (version strings, None when not installed), ``platform`` (as
        :func:`platform.platform` says it), ``os``, ``machine`` (e.g. "x86_64"), ``cpu``
        (model name), ``cpu_count``, ``numpy_simd`` (the SIMD target numpy
        dispatched float64 ``exp`` to, e.g. ``"X86_V3"`` = AVX2, None if numpy does not
        say) and ``blas`` (a list of ``{"library", "version", "kernel", "prefix"}``, one
        per BLAS loaded; ``kernel`` is OpenBLAS's, e.g. ``"Haswell"``).
    """
    env = {name: _version(dist) for name, dist in (
        ("freqid_casadi", "freqid_casadi"), ("numpy", "numpy"), ("scipy", "scipy"),
        ("casadi", "casadi"), ("control", "control"))}
    env["numpy"] = env["numpy"] or np.__version__
    env.update(python=platform.python_version(), platform=platform.platform(terse=True),
               os=platform.system(), machine=platform.machine(), cpu=_cpu(),
               cpu_count=os.cpu_count(), numpy_simd=_numpy_simd(), blas=_blas())
    return env


def environment_line(env):
    """One line for a report: CPU, numpy's SIMD level, BLAS kernel, versions.

    Parameters
    ----------
    env : dict
        As :func:`environment` returns it.

    Returns
    -------
    str
    """
    blas = sorted({f"{b['library']} {b['version']}" + (f" ({b['kernel']} kernel)"
                                                       if b.get("kernel") else "")
                   for b in env.get("blas") or []})
    simd = f" (SIMD {env['numpy_simd']})" if env.get("numpy_simd") else ""
    parts = [f"{env.get('cpu')} ({env.get('machine')}, {env.get('cpu_count')} CPUs, "
             f"{env.get('os')})",
             f"Python {env.get('python')}, numpy {env.get('numpy')}{simd}, "
             f"scipy {env.get('scipy')}, casadi {env.get('casadi')}, "
             f"freqid_casadi {env.get('freqid_casadi')}"]
    if blas:
        parts.append("BLAS: " + ", ".join(blas))
    return "; ".join(parts)


def computed_on(env):
    """The sentence a report states its machine with: ``Computed on `<line>`.``.

    Parameters
    ----------
    env : dict
        As :func:`environment` returns it, recorded when the numbers were computed (a
        report re-rendered from its JSON states the machine of its fits).

    Returns
    -------
    str
        One Markdown sentence (the line in a code span).
    """
    return f"Computed on `{environment_line(env)}`."


def computed_on_lines(env):
    """``[computed_on(env), ""]``, the lines a Markdown report inserts, or ``[]`` when
    ``env`` is None (a report rendered from a JSON written before it was recorded).

    Parameters
    ----------
    env : dict or None

    Returns
    -------
    list of str
    """
    return [computed_on(env), ""] if env else []

"""Helpers shared by the benchmark scripts: timing, number format, machine description."""

from __future__ import annotations

import importlib
import os
import platform
import time
import timeit
from collections.abc import Callable
from importlib import metadata

import numpy as np


def optional_import(name):
    """The module ``name``, or None when it is not installed."""
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


def best_time(fn: Callable[[], object], repeat: int, min_run: float) -> float:
    """Best-of-``repeat`` seconds per call of ``fn``, :mod:`timeit` style.

    The number of calls per repeat doubles until one repeat lasts ``min_run`` seconds; the
    minimum over ``repeat`` such repeats (timed with :func:`time.perf_counter`) is
    divided by that number.
    """
    timer = timeit.Timer(fn, timer=time.perf_counter)
    number = 1
    while timer.timeit(number) < min_run:
        number *= 2
    return min(timer.repeat(repeat=repeat, number=number)) / number


def best_of(fn: Callable[[], object], repeat: int) -> float:
    """Least wall time, s, of ``repeat`` single calls of ``fn`` (for calls too long to loop)."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def fmt(value: float) -> str:
    """Three significant digits, no exponent."""
    if value >= 100:
        return f"{value:.0f}"
    if value >= 10:
        return f"{value:.1f}"
    return f"{value:.2f}"


def machine_description(libraries: dict[str, bool], width: int = 16) -> list[str]:
    """Lines describing the CPU, Python, NumPy and the libraries compared (name -> installed)."""
    uname = platform.uname()
    cpu = platform.processor()
    if not cpu and os.path.exists("/proc/cpuinfo"):
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), "")
    lines = [
        f"machine : {uname.system} {uname.release} {uname.machine}, {cpu or 'unknown CPU'}, "
        f"{os.cpu_count()} CPUs",
        f"python  : {platform.python_version()}, numpy {np.__version__}",
    ]
    for lib, installed in libraries.items():
        version = metadata.version(lib) if installed else "not installed"
        lines.append(f"{lib:<{width}}: {version}")
    return lines

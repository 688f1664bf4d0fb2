"""Argument types of the command line: every number is checked when parsed, before any work.

``argparse`` calls these on the text of an option; a bad value is a usage error naming the option and
the value (exit 2), so a long run cannot fail at its end for a typo at its start.
"""

from __future__ import annotations

import argparse
import math

__all__ = ["integer", "number", "process_count"]


def integer(lo: int | None = None, hi: int | None = None):
    """An argparse type: a whole number in ``[lo, hi]`` (either bound optional)."""

    def parse(text: str) -> int:
        try:
            n = int(text.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if (lo is not None and n < lo) or (hi is not None and n > hi):
            raise argparse.ArgumentTypeError(f"expected a whole number {_range(lo, hi)}, got {text!r}")
        return n

    return parse


def process_count(text: str) -> int:
    """The argparse type of every ``--workers`` option: a number of processes, a whole number >= 1."""
    return integer(1)(text)


def number(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False):
    """An argparse type: a finite number in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``)."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        ok = math.isfinite(v) and (lo is None or (v > lo if lo_open else v >= lo)) and (hi is None or v <= hi)
        if not ok:
            want = " ".join(filter(None, ("expected a finite number", _range(lo, hi, lo_open))))
            raise argparse.ArgumentTypeError(f"{want}, got {text!r}")
        return v

    return parse


def _range(lo, hi, lo_open: bool = False) -> str:
    if lo is not None and hi is not None:
        return f"{'>' if lo_open else '>='} {lo:g} and <= {hi:g}"
    if lo is not None:
        return f"{'>' if lo_open else '>='} {lo:g}"
    return f"<= {hi:g}" if hi is not None else ""

"""Numbers as text, in one place: the cells of every table, report and CSV file the package writes (the
scores, the blocks, the HTML report, the benchmark, the claims, the paper reports) go through these.

A figure that is not there (None, or NaN: a run that diverged, a reading not taken) prints as the caller's
``missing`` text, "-" by default; an infinite one as "inf" unless the caller wants only finite figures. An
integer (a count) prints whole. Prose messages keep their own inline formats.
"""
from __future__ import annotations

import math
from numbers import Integral

__all__ = ["number", "csv_cell", "median_interval", "relative", "ratio", "fixed"]


def number(value, digits: int = 3, *, scale: float = 1.0, missing: str = "-", finite: bool = False) -> str:
    """``value * scale`` to ``digits`` significant digits, an integer whole; ``missing`` for None and NaN, and
    for an infinite value where ``finite``. ``scale`` 1e6 gives a length in metres in micrometres."""
    if value is None or value != value or (finite and not math.isfinite(value)):
        return missing
    if isinstance(value, Integral) and not isinstance(value, bool) and scale == 1.0:
        return f"{value:d}"
    return f"{value * scale:.{digits}g}"


def csv_cell(value, scale: float = 1.0) -> str:
    """A figure of a CSV file: 6 significant digits, an empty cell for one that is missing or not finite
    (spreadsheets and pandas read it as no value)."""
    return number(value, 6, scale=scale, missing="", finite=True)


def median_interval(median, low, high, digits: int = 3, *, scale: float = 1.0, narrow_digits: int | None = None) -> str:
    """``median [low, high]`` each to ``digits`` significant digits (:func:`number`), "-" without a median;
    to ``narrow_digits`` instead where given and the bounds would print alike (an interval too narrow to show
    at ``digits``)."""
    if median is None or median != median:
        return "-"
    if narrow_digits is not None and number(low, digits, scale=scale) == number(high, digits, scale=scale):
        digits = narrow_digits
    return (f"{number(median, digits, scale=scale)} "
            f"[{number(low, digits, scale=scale)}, {number(high, digits, scale=scale)}]")


def relative(value, reference) -> float | None:
    """``value / reference``; None where either is missing or the reference is zero or not finite."""
    if value is None or reference is None or not reference or not math.isfinite(reference):
        return None
    return value / reference


def ratio(value, reference, digits: int = 3) -> str:
    """:func:`relative` to ``digits`` significant digits, "-" where it is None."""
    return number(relative(value, reference), digits)


def fixed(value: float, decimals: int) -> str:
    """``value`` to ``decimals`` places (a resolution: a time to the sample time, an error to 1 nm), never
    "-0.000"."""
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text

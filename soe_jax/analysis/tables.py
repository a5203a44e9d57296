"""The analysis's tables and numbers, written one way: a markdown table from a header and rows, a
rate as a percentage, and a value over training seeds as mean ± sample standard deviation."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np


def markdown(header: Sequence[str], rows: Iterable[Sequence]) -> str:
  """A markdown table: the header, its rule, and a line per row (each cell as `str` gives it)."""
  lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
  lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
  return "\n".join(lines) + "\n"


def pct(x: float | None) -> str:
  """0.1234 -> '12.3%' ('-' for None)."""
  return "-" if x is None else f"{100 * x:.1f}%"


def rate(m: dict | None) -> str:
  """A phase record's success rate with its 95% Wilson interval and episodes: '12.3% [10.0%, 15.0%]
  (n=200)' ('-' for None)."""
  if m is None:
    return "-"
  return f"{pct(m['success_rate'])} [{pct(m['wilson_low'])}, {pct(m['wilson_high'])}] (n={m['num_rollouts']})"


def spread(xs, scale: float = 100, unit: str = "%", sign: str = "", fmt: str = ".1f") -> str:
  """Mean ± sample standard deviation over seeds of the values present in `xs` (None and NaN are
  absent), scaled; the mean alone for one seed, '-' for none."""
  xs = scale * np.asarray([x for x in xs if x is not None], float)
  xs = xs[~np.isnan(xs)]
  if not len(xs):
    return "-"
  mean = f"{xs.mean():{sign}{fmt}}"
  return f"{mean} ± {xs.std(ddof=1):{fmt}}{unit}" if len(xs) > 1 else f"{mean}{unit}"


def mean_std(xs) -> str:
  """Mean ± sample standard deviation over seeds at three significant digits (the value alone for one
  seed; '-' for none): the aggregate's raw numbers."""
  xs = [x for x in xs if x is not None]
  if not xs:
    return "-"
  return f"{np.mean(xs):.3g} ± {np.std(xs, ddof=1):.2g}" if len(xs) > 1 else f"{xs[0]:.3g}"

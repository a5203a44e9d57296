"""Finished runs -> one table over tasks x methods, paired with round 0 and the control.

  python -m soe_jax aggregate RUNS_DIR [--out=RUNS_DIR/comparison]

Finds every run directory under RUNS_DIR (a `metrics.jsonl` beside a `config.json`, with the
`outcomes.json` its report wrote) and writes `<out>.md` and `<out>.csv`: per task, method and variant
the numbers as mean ± std over training seeds, success pooled with its Wilson interval, and each
method's last round paired state by state with its round 0 and with the control of its seed (see
`soe_jax/analysis/aggregate.py`). Prints the table, then where it went.
"""

from __future__ import annotations

from soe_jax.analysis import aggregate
from soe_jax.runtime import cli

USAGE = "python -m soe_jax aggregate RUNS_DIR [--out=PATH]"

FLAGS = cli.Flags()
FLAGS.string("out", None, "Output path without extension (default RUNS_DIR/comparison).")


def _aggregate(argv: list[str]) -> None:
  (root,) = cli.positional(argv, "1", USAGE)
  runs, md, out = aggregate.write(root, FLAGS.out)
  print(md)
  print(f"{len(runs)} runs -> {out}.md, {out}.csv")


def main(argv: list[str] | None = None) -> None:
  cli.run(_aggregate, FLAGS, __doc__, argv)

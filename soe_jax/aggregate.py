"""Compare finished runs: one table over tasks x methods, mean ± std over seeds.

  python -m soe_jax.aggregate RUNS_DIR [--out=RUNS_DIR/comparison]

Finds every run directory under RUNS_DIR (a `metrics.jsonl` beside a `config.json`) and writes
`<out>.md` and `<out>.csv`; success rates carry the pooled episode count and 95% Wilson interval.
"""

from __future__ import annotations

import os

from absl import app, flags

flags.DEFINE_string("out", None, "Output path without extension (default RUNS_DIR/comparison).")
FLAGS = flags.FLAGS


def main(argv):
  if len(argv) != 2:
    raise app.UsageError("usage: python -m soe_jax.aggregate RUNS_DIR [--out=PATH]")
  from soe_jax import report

  root = argv[1]
  runs = report.find_runs(root)
  if not runs:
    raise app.UsageError(f"no run directories (metrics.jsonl + config.json) under {root!r}")
  md, csv_text = report.aggregate(runs)
  out = FLAGS.out or os.path.join(root, "comparison")
  with open(out + ".md", "w") as f:
    f.write(md)
  with open(out + ".csv", "w") as f:
    f.write(csv_text)
  print(md)
  print(f"{len(runs)} runs -> {out}.md, {out}.csv")


if __name__ == "__main__":
  app.run(main)

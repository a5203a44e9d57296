"""What the kept episodes of runs look like (lengths, spread, states), as a record.

  python -m soe_jax kept RUN_DIR [RUN_DIR ...] [--round=1] [--out=results/<study>/<name>.json]

For each run (a workdir of `run` or of a campaign), the episodes round `--round`'s exploration kept
and the run's demonstrations, each measured: its length, the commanded position's step at action-chunk
boundaries and inside chunks, the object's tilt, the grasps (see `soe_jax/analysis/kept.py`). Prints a
table with a row per task and method (episodes pooled over seeds) and a row of the demonstrations;
`--out` also writes the record (command, commit, machine, per run its method, seed and per-episode
numbers) for `results/`, where `python -m soe_jax results` tables it.
"""

from __future__ import annotations

from soe_jax.analysis import kept
from soe_jax.runtime import cli

USAGE = "python -m soe_jax kept RUN_DIR [RUN_DIR ...] [--round=1] [--out=FILE.json]"

FLAGS = cli.Flags()
FLAGS.integer("round", 1, "The exploration round whose kept episodes are measured.")
FLAGS.string("out", None, "Also write the record (for results/) here.")


def _kept(argv: list[str]) -> None:
  workdirs = cli.positional(argv, "1+", USAGE)
  record = kept.record(workdirs, FLAGS.round)
  print(kept.table(record["runs"]), end="")
  if FLAGS.out:
    kept.write_record(record, FLAGS.out)
    print(f"-> {FLAGS.out}")


def main(argv: list[str] | None = None) -> None:
  cli.run(_kept, FLAGS, __doc__, argv)

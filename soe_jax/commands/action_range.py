"""Round 0 on the workspace box against the demonstrations' action range, paired state by state and
bucketed by how far each evaluation state's object lies outside the demonstrations' box.

  python -m soe_jax action_range results/campaign-workspace/lift [--out=results/action-range/lift.json]

Reads the campaign results of the methods `control` and `control+range=demonstrations` for every seed
under the task's directory (`python -m soe_jax campaign ... --methods=control,control+range=demonstrations,...`),
prints the table, and with --out writes the record (command, commit, machine, per seed the distances and
both round 0s' per-state outcomes) that `python -m soe_jax results` tables.
"""

from __future__ import annotations

from soe_jax.analysis import action_range
from soe_jax.analysis.record import write_record
from soe_jax.runtime import cli, provenance

USAGE = "python -m soe_jax action_range RESULTS/<task> [--out=FILE.json]"

FLAGS = cli.Flags()
FLAGS.string("out", None, "Also write the record (for results/) here.")


def _action_range(argv: list[str]) -> None:
  (task_dir,) = cli.positional(argv, "1", USAGE)
  result = dict(provenance.header(), **action_range.record(task_dir))
  print(action_range.table(result["seeds"]), end="")
  if FLAGS.out:
    write_record(result, FLAGS.out, "action_range")
    print(f"-> {FLAGS.out}")


def main(argv: list[str] | None = None) -> None:
  cli.run(_action_range, FLAGS, __doc__, argv, compiles=True)

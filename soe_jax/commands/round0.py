"""A campaign arm's round 0 as a record for results/ (kind `round0`: its fit and its per-state evaluation),
tabled with the other records of its folder, each paired with the first on the same start states.

  python -m soe_jax round0 RESULTS/<task>/seed<k>/<arm> --inputs="what differs" --out=results/STUDY/NAME.json
"""

from __future__ import annotations

from soe_jax.runtime import cli

USAGE = 'python -m soe_jax round0 RUN_RESULTS --inputs="..." --out=FILE.json'

FLAGS = cli.Flags()
FLAGS.string("inputs", "-", "What this round 0 differs in (the table's `inputs` column).")
FLAGS.string("out", None, "Where the record goes.")


def _round0(argv: list[str]) -> None:
  (run_dir,) = cli.positional(argv, "1", USAGE)
  from soe_jax.analysis import round0
  from soe_jax.analysis.record import write_record

  result = round0.record(run_dir, FLAGS.inputs)  # (the command, commit and machine of the run)
  ev = result["evaluate"]
  print(
    f"{run_dir}: round 0 success {ev['success_rate']:.1%} of {ev['num_rollouts']}, fit {result['fit']['time_total_s']:.0f} s"
  )
  write_record(result, FLAGS.out, "round0")
  print(f"-> {FLAGS.out}")


def main(argv: list[str] | None = None) -> None:
  cli.run(_round0, FLAGS, __doc__, argv, required=("out",))

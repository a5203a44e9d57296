"""How often the tests behind the verdicts say "different" when nothing is, and how often they detect
5 points, on outcomes simulated as a campaign makes them, as a record.

  python -m soe_jax calibrate RESULTS_DIR --task=lift --nulls=FOLDER[:1+2+3],... [--replicates=20000]
      [--out=results/calibration/<task>.json]

The per-state difficulty comes from every evaluation of `--task` in RESULTS_DIR (a campaign's exported
runs); tau, the seed-to-seed spread of a fit, from the null comparisons `--nulls` (each folder's
control against its round 0, or `FOLDER:1+2+3`, each listed round of its control against the one
before it). Then per cell (tau 0 or measured; 3 or 5 seeds; effect 0 or +-5 points) the pooled CMH,
the unmoderated and the moderated seed-level test's rate of p < 0.05 (`soe_jax/analysis/calibration.py`).
"""

from __future__ import annotations

from soe_jax.analysis import calibration, record
from soe_jax.runtime import cli, provenance

USAGE = "python -m soe_jax calibrate RESULTS_DIR --task=TASK --nulls=FOLDER[:1+2+3],... [--out=FILE.json]"

FLAGS = cli.Flags()
FLAGS.string("task", None, "The task whose start states' difficulty the simulation draws.")
FLAGS.list("nulls", None, "The null comparisons that measure tau: FOLDER or FOLDER:ROUND+ROUND+...")
FLAGS.integer("replicates", calibration.REPLICATES, "Simulated campaigns per cell.", lower_bound=100)
FLAGS.integer("seed", 0, "The simulation's random seed.")
FLAGS.string("out", None, "Also write the record (for results/) here.")


def _calibrate(argv: list[str]) -> None:
  (folder,) = cli.positional(argv, "1", USAGE)
  source = provenance.header(argv)
  try:
    result = calibration.study(folder, FLAGS.task, FLAGS.nulls, FLAGS.replicates, FLAGS.seed)
  except ValueError as e:
    raise cli.UsageError(str(e)) from None
  print(calibration.table([result]), end="")
  if FLAGS.out:
    record.write_record(dict(source, **result), FLAGS.out, "calibration")
    print(f"-> {FLAGS.out}")


def main(argv: list[str] | None = None) -> None:
  cli.run(_calibrate, FLAGS, __doc__, argv, required=("task", "nulls"))

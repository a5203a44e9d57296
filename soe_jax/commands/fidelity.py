"""How faithful the exploration path is to the base path at the decisions runs recorded
(`soe_jax/analysis/fidelity.py`).

  python -m soe_jax fidelity RUN_DIR [RUN_DIR ...] [--samples=8] [--alphas=0,1,2] [--out=FILE.json]

Prints a table with a row per run (medians over its decisions, in mm); `--out` also writes the record
(command, commit, machine, per run its per-decision numbers) for `results/`.
"""

from __future__ import annotations

from soe_jax.analysis import fidelity
from soe_jax.analysis.record import write_record
from soe_jax.runtime import cli, provenance

USAGE = "python -m soe_jax fidelity RUN_DIR [RUN_DIR ...] [--samples=8] [--alphas=0,1,2] [--out=FILE.json]"

FLAGS = cli.Flags()
FLAGS.integer("samples", 8, "Chunks per decision from each path.", lower_bound=2)
FLAGS.list("alphas", ["0", "1", "2"], "The exploration path's scales.")
FLAGS.string("out", None, "Also write the record (for results/) here.")


def _fidelity(argv: list[str]) -> None:
  workdirs = cli.positional(argv, "1+", USAGE)
  try:
    alphas = tuple(float(a) for a in FLAGS.alphas)
  except ValueError:
    raise cli.UsageError(f"--alphas takes numbers, got {','.join(FLAGS.alphas)}") from None
  source = provenance.header()
  runs = [fidelity.measure(w, FLAGS.samples, alphas) for w in workdirs]
  print(fidelity.table(runs), end="")
  if FLAGS.out:
    write_record(dict(source, runs=runs), FLAGS.out, "fidelity")
    print(f"-> {FLAGS.out}")


def main(argv: list[str] | None = None) -> None:
  cli.run(_fidelity, FLAGS, __doc__, argv, compiles=True)

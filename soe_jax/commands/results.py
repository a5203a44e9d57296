"""Committed records under results/ -> tables; `--docs` regenerates the documents' tables.

  python -m soe_jax results RESULTS_DIR [ARM:REFERENCE ...]
  python -m soe_jax results --docs     # every generated table and figure in the README, RESULTS.md, BENCHMARKS.md

RESULTS_DIR holds records (`*.json`: a benchmark's, `converge`'s, `latent`'s, `kept`'s) or the runs a
campaign exported; the table is printed (see `soe_jax/analysis/results.py` for each kind). With pairs
of a campaign's methods, each arm against its reference instead, paired on every seed both ran. `--docs`,
from the repository's root, rewrites every table between `<!-- table: RESULTS_DIR -->` and
`<!-- /table -->` in README.md, RESULTS.md and BENCHMARKS.md from its folder, draws every figure
named by a line `<!-- figure: RESULTS_DIR PATH.png -->`, and prints a line per document and figure.
"""

from __future__ import annotations

from soe_jax.analysis import results
from soe_jax.runtime import cli
from soe_jax.runtime.errors import UserError

USAGE = "python -m soe_jax results RESULTS_DIR [ARM:REFERENCE ...] | --docs"

FLAGS = cli.Flags()
FLAGS.boolean(
  "docs", False, "Regenerate every table in README.md, RESULTS.md and BENCHMARKS.md from its results folder."
)


def _results(argv: list[str]) -> None:
  try:
    if FLAGS.docs:
      cli.positional(argv, "0", "python -m soe_jax results --docs (from the repository's root)")
      print("\n".join(results.docs()))
      return
    study, *pairs = cli.positional(argv, "1+", USAGE)
    print(results.table(study, pairs), end="")
  except FileNotFoundError as e:  # a folder without records, a document not here
    raise UserError(cli.message(e)) from None


def main(argv: list[str] | None = None) -> None:
  cli.run(_results, FLAGS, __doc__, argv)

"""Labels against states: a finished run's round-1 exploration with the actions at its decisions
replaced by another path's chunks, re-fitted and evaluated as a new arm (`soe_jax/experiment/relabel.py`).

  python -m soe_jax relabel SOURCE_RUN --labels=base|explore|recorded [--alpha=0] [--seed=0]
      [--workdir=<SOURCE_RUN's folder>/<method>]

The new run lies beside the source (its method `<source method>-relabel_<labels>...`), shares its round
0, and resumes at round 1's re-fit as `run` would; running the command again resumes it. `--results`
copies its small files beside a campaign's runs, where it pairs with their control. The last lines
printed are the run's report's path and numbers.
"""

from __future__ import annotations

import json
import os

from soe_jax.runtime import cli

USAGE = "python -m soe_jax relabel SOURCE_RUN --labels=base|explore|recorded [--alpha=A] [--seed=S]"

FLAGS = cli.Flags()
FLAGS.enum("labels", None, ["base", "explore", "recorded"], "Whose chunks label the recorded decisions.")
FLAGS.float("alpha", 0.0, "The exploration path's scale (labels=explore).", lower_bound=0.0)
FLAGS.integer("seed", 0, "The relabelling's sampling seed (another seed: a fresh draw of the same path).")
FLAGS.string("workdir", None, "The new run's directory (default: beside the source, named by its method).")
FLAGS.string(
  "results", None, "Also copy the finished run's small files to <results>/<task>/seed<k>/<method>/, as `campaign` does."
)
FLAGS.boolean("progress", True, "Progress bars.")


def _relabel(argv: list[str]) -> None:
  (source,) = cli.positional(argv, "1", USAGE)
  from soe_jax.analysis import aggregate, campaign, report  # (after the flags: --help imports nothing of JAX)
  from soe_jax.experiment import loop, relabel, rundir
  from soe_jax.runtime import provenance

  config = rundir.load_config(source)
  name = relabel.method_name(config.method, FLAGS.labels, FLAGS.alpha, FLAGS.seed)
  workdir = FLAGS.workdir or os.path.join(os.path.dirname(os.path.abspath(source)), name)
  header = provenance.header()
  relabel.make(source, workdir, FLAGS.labels, FLAGS.alpha, FLAGS.seed)
  config = rundir.load_config(workdir)
  loop.run(config, workdir, FLAGS.progress)
  summary = report.write(workdir)
  if FLAGS.results:
    dest = os.path.join(FLAGS.results, config.env.task, f"seed{config.seed}", config.method)
    campaign.export(workdir, dest, dict(header, source_run=os.path.abspath(source)))
    aggregate.write(FLAGS.results)
  print(f"report: {os.path.join(workdir, 'report.md')}")
  print(json.dumps(summary))


def main(argv: list[str] | None = None) -> None:
  cli.run(_relabel, FLAGS, __doc__, argv, required=("labels",),
          interrupted=cli.PHASES_SAVED, compiles=True)  # fmt: skip

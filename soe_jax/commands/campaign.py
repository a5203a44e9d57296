"""One task x one training seed of a comparison of methods, each run copied to `results/` as it finishes.

  python -m soe_jax campaign --config=configs/lift.py:cpu [--config.seed=K]
      [--methods=dp,sime,soe,soe_steer,control,dp+expert_data,soe+expert_data]
      [--workdir=runs/campaign] [--results=results/campaign] [--config.a.b=v]

Every method runs as `python -m soe_jax run` would run the config file with the method's presets added
(`+` joins presets: `soe+expert_data` is `:...,soe,expert_data`), in one process, so compiled programs
are shared; the training seed is the config's (`--config.seed=K`). Runs land in
`<workdir>/<task>/seed<k>/<method>/` and share the round 0 in `<workdir>/<task>/seed<k>/round0/`, built
by this command for this seed. After each run its small files (`command.json`: this command, the
equivalent `run` command, commit and machine; `config.json`, `metrics.jsonl`, `outcomes.json` with the
per-state outcomes, `report.md`) are copied to `<results>/<task>/seed<k>/<method>/`, and
`<results>/comparison.{md,csv}` is rewritten from everything there (`python -m soe_jax aggregate`).
Every method's config is checked before anything runs. Running the command again resumes where it
stopped. The last lines printed are the comparison's table.
"""

from __future__ import annotations

from soe_jax.analysis import campaign
from soe_jax.runtime import cli

USAGE = "python -m soe_jax campaign --config=configs/<task>.py[:PRESETS] [--config.seed=K] [--methods=...]"

FLAGS = cli.Flags()
FLAGS.config_flag("configs/<task>.py[:PRESETS], without a method (--config.seed=K: the training seed)")
FLAGS.list(
  "methods", list(campaign.METHODS), "Methods to run, in order: method presets, `+` joining presets of one method."
)
FLAGS.string("workdir", "runs/campaign", "Where the runs go (<workdir>/<task>/seed<k>/<method>).")
FLAGS.string("results", "results/campaign", "Where each finished run's small files go.")
FLAGS.boolean("progress", True, "Progress bars.")


def _campaign(argv: list[str]) -> None:
  cli.positional(argv, "0", USAGE)
  spec, overrides = FLAGS.config_file()
  print(campaign.campaign(spec, overrides, FLAGS.methods, FLAGS.workdir, FLAGS.results, FLAGS.progress))


def main(argv: list[str] | None = None) -> None:
  cli.run(
    _campaign,
    FLAGS,
    __doc__,
    argv,
    required=("config",),
    interrupted=cli.PHASES_SAVED,
    compiles=True,
  )

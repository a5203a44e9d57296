"""A comparison of methods over tasks x training seeds, each run copied to `results/` as it finishes.

  python -m soe_jax campaign --config=configs/lift.py:cpu [--seeds=0,1,2] [--tasks=lift,can]
      [--methods=dp,sime,soe,soe_steer,control,dp+expert_data,soe+expert_data] [--executor=local|slurm]
      [--workdir=runs/campaign] [--results=results/campaign] [--config.a.b=v]

Every method runs as `python -m soe_jax run` would run the config file with the method's presets added
(`+` joins presets: `soe+expert_data` is `:...,soe,expert_data`). The tasks are the config files of
those names beside `--config`'s, with its presets and overrides (none: `--config`'s task); the training
seeds are `--seeds` (none: the config's, or `--config.seed=K`). For each task and seed, runs land in
`<workdir>/<task>/seed<k>/<method>/` and share the round 0 in `<workdir>/<task>/seed<k>/round0/`, built
by this command for this seed. After each run its small files (`command.json`: this command, the
equivalent `run` command, commit and machine; `config.json`, `metrics.jsonl`, `outcomes.json` with the
per-state outcomes, `report.md`) are copied to `<results>/<task>/seed<k>/<method>/`, and
`<results>/comparison.{md,csv}` is rewritten from everything there (`python -m soe_jax aggregate`).
Every method's config is checked before anything runs or is queued.

`--executor=local` runs everything here, one run after another (compiled programs shared); the last
lines printed are the comparison's table. `--executor=slurm` queues it on a SLURM cluster through
submitit and returns: per task and seed, round 0 as one job and every method as a job of an array that
starts once round 0's job has succeeded, each job asking for the config's `slurm` section (partition,
time_min, cpus, gpus, mem_gb; `--config.slurm.partition=gpu`); the table is rewritten as each run ends,
so it is whole when the last ends. Running the same command again resumes where it stopped (with
`slurm`, it queues only the runs not finished, and round 0's job only where round 0 is not made).
"""

from __future__ import annotations

import sys

from soe_jax.analysis import campaign
from soe_jax.runtime import cli

USAGE = "python -m soe_jax campaign --config=configs/<task>.py[:PRESETS] [--seeds=0,1,2] [--methods=...]"
EXECUTORS = ("local", "slurm")

FLAGS = cli.Flags()
FLAGS.config_flag("configs/<task>.py[:PRESETS], without a method (--config.seed=K: the training seed)")
FLAGS.list(
  "methods", list(campaign.METHODS), "Methods to run, in order: method presets, `+` joining presets of one method."
)
FLAGS.list("tasks", [], "Tasks: config files of these names beside --config's, with its presets (none: --config's).")
FLAGS.list("seeds", [], "Training seeds (none: the config's, or --config.seed's).")
FLAGS.enum("executor", "local", EXECUTORS, "Where the runs run: here, one after another, or as SLURM jobs.")
FLAGS.string("workdir", "runs/campaign", "Where the runs go (<workdir>/<task>/seed<k>/<method>).")
FLAGS.string("results", "results/campaign", "Where each finished run's small files go.")
FLAGS.boolean("progress", True, "Progress bars (local; SLURM jobs draw none).")


def _campaign(argv: list[str]) -> None:
  cli.positional(argv, "0", USAGE)
  spec, overrides = FLAGS.config_file()
  grid = campaign.grid(spec, overrides, FLAGS.tasks, FLAGS.seeds)
  planned = [campaign.arms(s, o, FLAGS.methods, FLAGS.workdir, FLAGS.results) for s, o in grid]
  if FLAGS.executor == "local":
    print(campaign.run_local([arm for arms in planned for arm in arms], FLAGS.progress))
    return
  from soe_jax.analysis import slurm  # (submitit, only here)

  for line in slurm.submit(planned, FLAGS.workdir, sys.argv):
    print(line, flush=True)
  print(f"`squeue --me` lists the jobs; {FLAGS.results}/comparison.md is rewritten as each run ends "
        f"(`python -m soe_jax aggregate {FLAGS.results}` at any time)")  # fmt: skip


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

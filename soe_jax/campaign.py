"""One task x one training seed of a comparison of methods, each run committed to `results/` as it
finishes.

  python -m soe_jax.campaign --config=configs/lift.py:cpu --seed=0 \
      [--methods=dp,sime,soe,soe_steer,control,dp+expert_data,soe+expert_data] \
      [--workdir=runs/campaign] [--results=results/campaign] [--config.a.b=v]

Every method runs as `python -m soe_jax.main` would run the config file with the method's presets
added (`+` joins presets: `soe+expert_data` is `:...,soe,expert_data`), in one process, so compiled
programs are shared. Runs land in `<workdir>/<task>/seed<k>/<method>/` and share the round 0 in
`<workdir>/<task>/seed<k>/round0/`, built by this command for this seed. After each run its small
files (`command.json`: this command, the equivalent `main` command, commit and machine; `config.json`,
`metrics.jsonl`, `outcomes.json` with the per-state outcomes, `report.md`) are copied to
`<results>/<task>/seed<k>/<method>/`, and `<results>/comparison.{md,csv}` is rewritten from everything
there (`python -m soe_jax.aggregate`). Running the command again resumes where it stopped.
"""

from __future__ import annotations

import os
import shutil

from absl import flags
from ml_collections import config_flags

from soe_jax import cli
from soe_jax.errors import UserError

FLAGS = flags.FLAGS


def define_flags() -> None:
  """The command's flags, defined only when it runs (its functions are imported beside other commands
  that define `--config` too)."""
  config_flags.DEFINE_config_file("config", None, "configs/<task>.py[:PRESETS], without a method", lock_config=True)
  flags.DEFINE_integer("seed", 0, "The training seed (`config.seed`).")
  flags.DEFINE_list(
    "methods",
    ["dp", "sime", "soe", "soe_steer", "control", "dp+expert_data", "soe+expert_data"],
    "Methods to run, in order: method presets, `+` joining presets of one method.",
  )
  flags.DEFINE_string("workdir", "runs/campaign", "Where the runs go (<workdir>/<task>/seed<k>/<method>).")
  flags.DEFINE_string("results", "results/campaign", "Where each finished run's small files go.")
  flags.DEFINE_bool("progress", True, "Progress bars.")


# A run's files that go into results/ (everything else, checkpoints and data, stays in the workdir).
EXPORTED = ("config.json", "metrics.jsonl", "outcomes.json", "report.md")


def main_command(spec: str, presets: str, overrides: dict, workdir: str, round0_dir: str) -> str:
  """The `python -m soe_jax.main` command that runs one method of the campaign on its own."""
  spec = f"{spec}{',' if ':' in spec else ':'}{presets}"
  args = [f"--config={spec}"] + [f"--config.{k}={v}" for k, v in overrides.items()]
  args += [f"--config.rounds.round0_dir={round0_dir}", f"--workdir={workdir}"]
  return " ".join(["python -m soe_jax.main"] + args)


def export(workdir: str, dest: str, source: dict) -> None:
  """Copy a finished run's small files to `dest`, with `source` as `command.json`."""
  from soe_jax import rundir

  os.makedirs(dest, exist_ok=True)
  for name in EXPORTED:
    shutil.copyfile(os.path.join(workdir, name), os.path.join(dest, name))
  rundir.write_json(os.path.join(dest, "command.json"), source)


def campaign(spec: str, overrides: dict, seed: int, methods: list[str], root: str, results: str, progress: bool):
  """Run `methods` for one seed (see the module's docstring); returns the comparison's markdown."""
  from soe_jax import aggregate, configfile, loop, provenance, validation

  overrides = dict(overrides, seed=seed)
  configs = {}  # {the method's presets: its config}, every one checked before anything runs
  for m in methods:
    presets = m.replace("+", ",")
    try:
      configs[presets] = configfile.load(spec, presets, overrides)
    except ValueError as e:
      raise UserError(f"method {m!r}: {e}") from None
    validation.check(configs[presets])
  task = next(iter(configs.values())).env.task
  base = os.path.join(root, task, f"seed{seed}")
  header = provenance.header()
  md = ""
  for presets, config in configs.items():
    config.rounds.round0_dir = os.path.join(base, "round0")
    workdir = os.path.join(base, config.method)
    print(f"== {task} seed {seed}: {config.method}", flush=True)
    loop.run(config, workdir, progress)
    command = main_command(spec, presets, overrides, workdir, config.rounds.round0_dir)
    export(workdir, os.path.join(results, task, f"seed{seed}", config.method), dict(header, main_command=command))
    md, csv_text = aggregate.aggregate(aggregate.find_runs(results))
    for ext, text in (("md", md), ("csv", csv_text)):
      with open(os.path.join(results, f"comparison.{ext}"), "w") as f:
        f.write(text)
  return md


def main(argv):
  spec, overrides = cli.config_file(argv, FLAGS["config"])
  print(campaign(spec, overrides, FLAGS.seed, FLAGS.methods, FLAGS.workdir, FLAGS.results, FLAGS.progress))


if __name__ == "__main__":
  define_flags()
  cli.run(main, interrupted="interrupted: the finished phases are saved; run the same command to resume")

"""A comparison of methods over tasks and training seeds, each run committed to `results/` as it finishes
(`python -m soe_jax campaign` runs it).

Every method runs as `python -m soe_jax run` would run the config file with the method's presets added
(`+` joins presets: `soe+expert_data` is `:...,soe,expert_data`). The training seed is the config's
(`--config.seed=K`); `grid` gives the config file and overrides of each task and seed of a whole
campaign. Runs land in `<workdir>/<task>/seed<k>/<method>/` (an `Arm` each) and share the round 0 in
`<workdir>/<task>/seed<k>/round0/`, built by the campaign for this seed. After each run its small files
(`command.json`: the campaign's command, the equivalent `run` command, commit and machine;
`config.json`, `metrics.jsonl`, `outcomes.json` with the per-state outcomes, `report.md`) are copied to
`<results>/<task>/seed<k>/<method>/`, and `<results>/comparison.{md,csv}` is rewritten from everything
there (`python -m soe_jax aggregate`). Running the campaign again resumes where it stopped.

The arms run one after another in this process, so compiled programs are shared (`run_local`, the
`local` executor); or, on a cluster, round 0 as a job and the arms as jobs after it
(`analysis/slurm.py`), with `make_round0` and `run_arm` from here.
"""

from __future__ import annotations

import dataclasses
import os

import ml_collections

from soe_jax.analysis import aggregate, report
from soe_jax.experiment import loop, rundir, validation
from soe_jax.runtime import atomic, configfile, faults, locking, provenance
from soe_jax.runtime.errors import UserError

METHODS = ("dp", "sime", "soe", "soe_steer", "control", "dp+expert_data", "soe+expert_data")
# A run's files that go into results/ (everything else, checkpoints and data, stays in the workdir).
EXPORTED = ("config.json", "metrics.jsonl", "outcomes.json", "report.md")


def main_command(spec: str, presets: str, overrides: dict, workdir: str, round0_dir: str) -> str:
  """The `python -m soe_jax run` command that runs one method of the campaign on its own."""
  spec = f"{spec}{',' if ':' in spec else ':'}{presets}"
  args = [f"--config={spec}"] + [f"--config.{k}={v}" for k, v in overrides.items()]
  args += [f"--config.rounds.round0_dir={round0_dir}", f"--workdir={workdir}"]
  return " ".join(["python -m soe_jax run"] + args)


def export(workdir: str, dest: str, source: dict) -> None:
  """Copy a finished run's small files to `dest`, with `source` as `command.json`."""
  os.makedirs(dest, exist_ok=True)
  atomic.remove_stale(dest)
  with faults.site("results_export"):
    for name in EXPORTED:
      atomic.copy(os.path.join(workdir, name), os.path.join(dest, name))
    atomic.write_json(os.path.join(dest, "command.json"), dict(kind="run", **source))


def results_dir(results: str, config: ml_collections.ConfigDict) -> str:
  """Where a run of `config` is copied in the results folder `results`: <results>/<task>/seed<k>/<method>."""
  return os.path.join(results, config.env.task, f"seed{config.seed}", config.method)


def publish(workdir: str, config: ml_collections.ConfigDict, results: str, source: dict) -> str:
  """Copy the finished run in `workdir` into `results` (`export`, with `source` as `command.json`) and
  rewrite the folder's comparison, one process at a time -> the comparison's markdown."""
  with locking.held(os.path.join(results, ".lock")):  # (arms of a cluster's campaign end at once)
    export(workdir, results_dir(results, config), source)
    return aggregate.write(results)[1]


def configs(spec: str, overrides: dict, methods: list[str]) -> tuple[int, dict, dict]:
  """-> (the seed, the overrides with `seed` last, {the method's presets: its config}), every config
  loaded and checked (`UserError` otherwise). The seed is `overrides`' or else the config file's."""
  out = {}
  for m in methods:
    presets = m.replace("+", ",")
    try:
      out[presets] = configfile.load(spec, presets, overrides)
    except ValueError as e:
      raise UserError(f"method {m!r}: {e}") from None
    validation.check(out[presets])
  names = {}
  for presets, c in out.items():  # (a variant that changes nothing under these presets names no arm)
    if c.method in names:
      raise UserError(f"methods {names[c.method]!r} and {presets!r} are the same arm {c.method!r} under {spec!r}")
    names[c.method] = presets
  seeds = {int(c.seed) for c in out.values()}
  if len(seeds) != 1:
    raise UserError(f"the methods' configs have different seeds {sorted(seeds)}; give one with --config.seed=K")
  (seed,) = seeds
  # The seed always among the overrides, last: the exported `run` commands name it.
  return seed, {k: v for k, v in overrides.items() if k != "seed"} | {"seed": seed}, out


def grid(spec: str, overrides: dict, tasks: list[str], seeds: list[str]) -> list[tuple[str, dict]]:
  """(config file spec, overrides) of each task x training seed of a campaign, task by task: `tasks`
  names config files beside `spec`'s, with its presets (`configs/lift.py:cpu` and `can` ->
  `configs/can.py:cpu`; none: `spec`'s own), `seeds` the seeds (none: the config's or `--config.seed`'s).
  `UserError` for a task without a config file, a seed that is no integer or is given twice."""
  path, colon, presets = spec.partition(":")
  specs = [spec]
  if tasks:
    if len(set(tasks)) < len(tasks):
      raise UserError(f"--tasks names a task twice: {','.join(tasks)}")
    files = [os.path.join(os.path.dirname(path), f"{task}.py") for task in tasks]
    for file in files:
      configfile.check(configfile.resolve(file))
    specs = [f"{file}{colon}{presets}" for file in files]
  if not seeds:
    return [(s, overrides) for s in specs]
  if "seed" in overrides:
    raise UserError("give the training seeds once: --seeds=0,1,2 or --config.seed=K, not both")
  try:
    numbers = [int(s) for s in seeds]
  except ValueError:
    raise UserError(f"--seeds takes integers, got {','.join(seeds)}") from None
  if len(set(numbers)) < len(numbers):
    raise UserError(f"--seeds names a seed twice: {','.join(seeds)}")
  return [(s, overrides | {"seed": k}) for s in specs for k in numbers]


@dataclasses.dataclass(frozen=True)
class Arm:
  """One method of a campaign's task and seed, ready to run: its checked config (its round 0 in the
  seed's shared directory), its run directory, the results folder it is copied to, and the `run`
  command that runs it alone."""

  config: ml_collections.ConfigDict
  workdir: str
  results: str
  command: str

  @property
  def name(self) -> str:
    return f"{self.config.env.task} seed {self.config.seed}: {self.config.method}"

  @property
  def dir(self) -> rundir.RunDir:
    """Its run directory's files (its round 0's among them, shared with every arm of the seed whose
    round 0 is the same)."""
    return rundir.RunDir(self.workdir, self.config)

  def finished(self) -> bool:
    """Whether its run has finished and been copied to the results folder."""
    copied = os.path.exists(os.path.join(results_dir(self.results, self.config), "command.json"))
    return copied and rundir.finished(self.workdir, self.config)


def arms(spec: str, overrides: dict, methods: list[str], root: str, results: str) -> list[Arm]:
  """The arms of `methods` for the task and seed of `spec` with `overrides`, under the runs root `root`,
  copied to `results`; every config checked (`UserError`) before anything is written."""
  seed, overrides, checked = configs(spec, overrides, methods)
  task = next(iter(checked.values())).env.task
  base = os.path.join(root, task, f"seed{seed}")
  out = []
  for presets, config in checked.items():
    config.rounds.round0_dir = os.path.join(base, "round0")
    workdir = os.path.join(base, config.method)
    command = main_command(spec, presets, overrides, workdir, config.rounds.round0_dir)
    out.append(Arm(config, workdir, results, command))
  return out


def run_arm(arm: Arm, header: dict, progress: bool) -> str:
  """Run (or resume) one arm, write its report, copy it to its results folder with `header` (the
  campaign's command, commit, machine) and rewrite the folder's comparison -> its markdown."""
  print(f"== {arm.name}", flush=True)
  loop.run(arm.config, arm.workdir, progress)
  report.write(arm.workdir)
  return publish(arm.workdir, arm.config, arm.results, dict(header, main_command=arm.command))


def make_round0(arms: list[Arm], progress: bool) -> None:
  """Each different round 0 of `arms`, once, in the run of the first arm that has it (which then
  resumes after it)."""
  made = set()
  for arm in arms:
    if arm.dir.round0 not in made:
      loop.run_round0(arm.config, arm.workdir, progress)
      made.add(arm.dir.round0)


def round0_made(arms: list[Arm]) -> bool:
  """Whether every round 0 of `arms` is finished (evaluated)."""
  return all(atomic.read_record(arm.dir.phase_path(0, "evaluate")) is not None for arm in arms)


def run_local(arms: list[Arm], progress: bool) -> str:
  """Run `arms` one after another in this process (the `local` executor; round 0 in the first arm of
  each) -> the comparison's markdown after the last."""
  header = provenance.header()
  md = ""
  for arm in arms:
    md = run_arm(arm, header, progress)
  return md


def campaign(spec: str, overrides: dict, methods: list[str], root: str, results: str, progress: bool) -> str:
  """Run `methods` for the seed of `spec` with `overrides` (see the module's docstring); returns the
  comparison's markdown. Every method's config is checked before anything runs."""
  return run_local(arms(spec, overrides, methods, root, results), progress)

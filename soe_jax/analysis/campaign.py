"""One task x one training seed of a comparison of methods, each run committed to `results/` as it
finishes (`python -m soe_jax campaign` runs it).

Every method runs as `python -m soe_jax run` would run the config file with the method's presets added
(`+` joins presets: `soe+expert_data` is `:...,soe,expert_data`), in one process, so compiled programs
are shared. The training seed is the config's (`--config.seed=K`). Runs land in
`<workdir>/<task>/seed<k>/<method>/` and share the round 0 in `<workdir>/<task>/seed<k>/round0/`, built
by the campaign for this seed. After each run its small files (`command.json`: the campaign's command,
the equivalent `run` command, commit and machine; `config.json`, `metrics.jsonl`, `outcomes.json` with
the per-state outcomes, `report.md`) are copied to `<results>/<task>/seed<k>/<method>/`, and
`<results>/comparison.{md,csv}` is rewritten from everything there (`python -m soe_jax aggregate`).
Running the campaign again resumes where it stopped.
"""

from __future__ import annotations

import os

from soe_jax.analysis import aggregate, report
from soe_jax.experiment import loop, validation
from soe_jax.runtime import atomic, configfile, faults, provenance
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


def campaign(spec: str, overrides: dict, methods: list[str], root: str, results: str, progress: bool) -> str:
  """Run `methods` for the seed of `spec` with `overrides` (see the module's docstring); returns the
  comparison's markdown. Every method's config is checked before anything runs."""
  seed, overrides, checked = configs(spec, overrides, methods)
  task = next(iter(checked.values())).env.task
  base = os.path.join(root, task, f"seed{seed}")
  header = provenance.header()
  md = ""
  for presets, config in checked.items():
    config.rounds.round0_dir = os.path.join(base, "round0")
    workdir = os.path.join(base, config.method)
    print(f"== {task} seed {seed}: {config.method}", flush=True)
    loop.run(config, workdir, progress)
    report.write(workdir)
    command = main_command(spec, presets, overrides, workdir, config.rounds.round0_dir)
    export(workdir, os.path.join(results, task, f"seed{seed}", config.method), dict(header, main_command=command))
    md = aggregate.write(results)[1]
  return md

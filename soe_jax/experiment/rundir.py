"""A run's directory: everything about its files, in one place.

  <workdir>/config.json               the run's config (a different one is refused, naming the fields)
  <workdir>/metrics.jsonl, tb/        the log (`runlog`)
  <workdir>/report.md, outcomes.json  the report and every evaluation's per-state outcomes (`report`)
  <workdir>/rounds/<r>/<phase>.json   each finished phase's record (explore, fit, evaluate)
  <workdir>/rounds/<r>/ckpt/          round r's policy
  <workdir>/rounds/<r>/<phase>_episodes.hdf5  the phase's first `log.videos` episodes (for videos)
  <workdir>/videos/                   those episodes drawn to MP4 (`video`)
  <workdir>/data/round_<r>.hdf5       the episodes round r kept
  <workdir>/data/steered_round_<r>.hdf5  episodes steered by hand with round r's policy
  <round0>/{demos.hdf5, fit.json, evaluate.json, evaluate_episodes.hdf5, ckpt/}  round 0, shared (below)

Round 0 depends only on the task, data, policy, fit, rollout and evaluation settings, so it is stored
once in `rounds.round0_dir` (default `<workdir>/../round0`) under `<task>-<hash of those fields>` and
every method run beside it starts from the same policy. Files are written atomically (write, then
rename), and `RunDir.once` runs a phase only if its record is missing, so an interrupted run resumes
after its last finished phase.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from typing import Any

import ml_collections

from soe_jax.data import episodes, hdf5
from soe_jax.experiment import runlog, schema
from soe_jax.runtime import atomic, configfile, faults
from soe_jax.runtime.errors import UserError
from soe_jax.train import checkpoint
from soe_jax.train.partial import PartialFit

CONFIG_FILE = "config.json"


def plain(config: ml_collections.ConfigDict) -> dict:
  return json.loads(config.to_json())


def config_diff(saved: dict, current: dict) -> list[str]:
  """Fields whose values differ, as 'a.b: saved -> current'."""
  a, b = runlog.flatten(saved), runlog.flatten(current)
  missing = "<missing>"
  return [
    f"{k}: {a.get(k, missing)!r} -> {b.get(k, missing)!r}"
    for k in sorted(set(a) | set(b))
    if a.get(k, missing) != b.get(k, missing)
  ]


def with_added(saved: dict) -> dict:
  """`saved` with the `ADDED` fields (and its strategy's `ADDED_SETTINGS`) it lacks set to their old
  behaviour's values."""
  saved = json.loads(json.dumps(saved))
  for field, value in schema.ADDED.items():
    *sections, name = field.split(".")
    d = saved
    for part in sections:
      d = d.setdefault(part, {})
    d.setdefault(name, value)
  strategy = saved.get("explore", {}).get("strategy", {})
  if isinstance(strategy, dict):
    for name, value in schema.ADDED_SETTINGS.get(strategy.get("name"), {}).items():
      strategy.setdefault("kwargs", {}).setdefault(name, value)
  return saved


def check_renamed(saved: dict, path: str) -> None:
  """Refuse a config saved with fields that have since been renamed, naming them."""
  flat = runlog.flatten(saved)
  old = sorted({o for k in flat for o in schema.RENAMED if k == o or (o.endswith(".") and k.startswith(o))})
  if old:
    moves = "\n  ".join(f"{o.rstrip('.')} -> {schema.RENAMED[o]}" for o in old)
    raise UserError(
      f"{path} was written with config fields that have been renamed:\n  {moves}\n"
      "this run directory cannot be resumed; start the run again in a new --workdir"
    )


def check_config(workdir: str, config: ml_collections.ConfigDict) -> None:
  """Save the config in a new workdir; refuse one that differs from a workdir's saved config, except
  for more `rounds.num_rounds` (extending a finished run, e.g. after steering its last round) and
  the logging settings (`NOT_COMPARED`)."""
  path = os.path.join(workdir, CONFIG_FILE)
  current = plain(config)
  if not os.path.exists(path):
    with faults.site("run_config"):
      atomic.write_json(path, current)
    return
  saved = atomic.read_json(path)
  check_renamed(saved, path)
  saved = with_added(saved)
  extended = current["rounds"]["num_rounds"] > saved["rounds"]["num_rounds"]
  if extended:
    saved["rounds"]["num_rounds"] = current["rounds"]["num_rounds"]
  diff = [d for d in config_diff(saved, current) if not d.startswith(schema.NOT_COMPARED)]
  if diff:
    raise UserError(
      f"the config does not match the one saved in {path}; differing fields:\n  "
      + "\n  ".join(diff)
      + "\nuse a new --workdir, or the saved config"
    )
  if extended:
    with faults.site("run_config"):
      atomic.write_json(path, current)


def load_config(workdir: str) -> ml_collections.ConfigDict:
  """The config saved in a run's workdir."""
  path = os.path.join(workdir, CONFIG_FILE)
  if not os.path.exists(path):
    raise UserError(f"{workdir!r} is not a run directory: {CONFIG_FILE} is missing")
  saved = atomic.read_json(path)
  check_renamed(saved, path)
  return ml_collections.ConfigDict(with_added(saved))


def round0_key(config: ml_collections.ConfigDict) -> str:
  fields = {k: v for k, v in plain(config).items() if k not in schema.NOT_ROUND0}
  for field in schema.NOT_ROUND0_FIELDS + tuple(schema.ADDED):  # added fields only where they do what their absence did
    *sections, name = field.split(".")
    d = fields
    for part in sections:
      d = d.get(part, {})
    if name in d and (field in schema.NOT_ROUND0_FIELDS or d[name] == schema.ADDED[field]):
      del d[name]
  fields["checkpoint_format"] = checkpoint.STATE_FORMAT  # a round 0 saved in another format is not reused
  digest = hashlib.sha1(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:10]
  return f"{config.env.task}-{digest}"


def default_workdir(config: ml_collections.ConfigDict, spec: str) -> str:
  """runs/<task>-<method>-seed<k>, and `-<hash>` of the fields (other than the seed) in which `config`
  differs from what the config file `spec` (`configs/<task>.py[:PRESETS]`) gives, so the same command
  names the same run and runs differing only by an override do not collide."""
  diff = config_diff(plain(configfile.load(spec)), plain(config))
  diff = [d for d in diff if not d.startswith(("seed:",) + schema.NOT_COMPARED)]
  name = f"{config.env.task}-{config.method}-seed{config.seed}"
  if diff:
    name += "-" + hashlib.sha1("\n".join(diff).encode()).hexdigest()[:6]
  return os.path.join("runs", name)


def finished(workdir: str, config: ml_collections.ConfigDict) -> bool:
  """Whether the run in `workdir` has evaluated the last round `config` asks for."""
  done = runlog.read_metrics(workdir) if os.path.exists(os.path.join(workdir, CONFIG_FILE)) else []
  return bool(done) and (done[-1]["round"], done[-1]["phase"]) == (int(config.rounds.num_rounds), "evaluate")


def status(workdir: str, config: ml_collections.ConfigDict) -> str:
  """Whether running `config` in `workdir` starts, resumes (after which phase) or finds it finished."""
  done = runlog.read_metrics(workdir)
  if not os.path.exists(os.path.join(workdir, CONFIG_FILE)):
    return "starting"
  last = done[-1] if done else None
  if finished(workdir, config):
    return f"already finished ({last['round']} rounds); rewriting its report"
  said = f"resuming after round {last['round']} {last['phase']}" if last else "resuming round 0"
  fitting = 0 if last is None else last["round"] if last["phase"] == "explore" else None  # the next fit
  if fitting is not None:
    step = PartialFit(RunDir(workdir, config).partial_fit_dir(fitting)).latest()
    if step is not None:
      said += f" (round {fitting}'s fit from step {step})"
  return said


class RunDir:
  """The files of the run in `workdir` with `config`."""

  def __init__(self, workdir: str, config: ml_collections.ConfigDict):
    self.path = os.path.abspath(workdir)
    self.config = config
    base = config.rounds.round0_dir or os.path.join(os.path.dirname(self.path), "round0")
    self.round0 = os.path.join(base, round0_key(config))

  @classmethod
  def create(cls, workdir: str, config: ml_collections.ConfigDict) -> RunDir:
    """Make (or reopen, checking the config) the run directory; write its config. Temporary files a killed
    run left are removed."""
    os.makedirs(workdir, exist_ok=True)
    atomic.remove_stale(workdir)
    check_config(workdir, config)
    return cls(workdir, config)

  @classmethod
  def open(cls, workdir: str) -> RunDir:
    """An existing run directory, with its saved config."""
    return cls(workdir, load_config(workdir))

  # -- paths ------------------------------------------------------------------------------------
  def round_dir(self, r: int) -> str:
    """Where round r's phases and policy live (round 0: the shared round-0 directory)."""
    return self.round0 if r == 0 else os.path.join(self.path, "rounds", str(r))

  def phase_path(self, r: int, phase: str) -> str:
    return os.path.join(self.round_dir(r), f"{phase}.json")

  def ckpt_dir(self, r: int) -> str:
    return os.path.join(self.round_dir(r), "ckpt")

  @property
  def demos_path(self) -> str:
    """The run's demonstrations, in its shared round-0 directory."""
    return os.path.join(self.round0, "demos.hdf5")

  def data_path(self, r: int) -> str:
    """The episodes round r kept."""
    return os.path.join(self.path, "data", f"round_{r}.hdf5")

  def steered_path(self, r: int) -> str:
    """Where episodes steered with round r's policy go."""
    return os.path.join(self.path, "data", f"steered_round_{r}.hdf5")

  # -- a fit in progress -------------------------------------------------------------------------
  def partial_fit_dir(self, r: int) -> str:
    return os.path.join(self.round_dir(r), "fit_partial")

  # -- what is there ----------------------------------------------------------------------------
  def has_checkpoint(self, r: int) -> bool:
    return os.path.exists(os.path.join(self.ckpt_dir(r), checkpoint.CONFIG_FILE))

  def checkpoint_dir(self, r: int) -> str:
    """Round r's saved policy; an error if it has none yet."""
    if not self.has_checkpoint(r):
      raise FileNotFoundError(f"round {r} of {self.path!r} has no checkpoint at {self.ckpt_dir(r)} (not run yet?)")
    return self.ckpt_dir(r)

  def last_round(self) -> int:
    """The last round with a saved checkpoint (0 if only round 0 has one)."""
    return max((r for r in self.rounds() if r and self.has_checkpoint(r)), default=0)

  def save_kept(self, r: int, kept: list[dict], meta: dict) -> None:
    """Write the episodes round r kept (`meta` goes into the file's env_args)."""
    with faults.site("episodes"):
      hdf5.write_episodes(self.data_path(r), kept, dict(meta, source=f"round {r} exploration"))

  def kept(self, record: dict) -> list[dict]:
    """The episodes the explore phase of `record` kept."""
    return hdf5.read_episodes(self.data_path(record["round"]))[0] if record["num_episodes"] else []

  def shown_path(self, r: int, phase: str) -> str:
    """Where round r's phase stores its first episodes, to be watched."""
    return os.path.join(self.round_dir(r), f"{phase}_episodes.hdf5")

  def save_shown(self, r: int, phase: str, episodes: list[dict], meta: dict) -> None:
    """Store round r's first episodes of `phase` (nothing when there are none: `log.videos=0`)."""
    if not episodes:
      return
    with faults.site("episodes"):
      hdf5.write_episodes(self.shown_path(r, phase), episodes, dict(meta, source=f"round {r} {phase}, first episodes"))

  def shown(self, r: int, phase: str) -> list[dict]:
    """Round r's stored first episodes of `phase` (none if it stored none)."""
    path = self.shown_path(r, phase)
    return hdf5.read_episodes(path)[0] if os.path.exists(path) else []

  def shown_rounds(self) -> list[int]:
    """The rounds with stored episodes of either phase."""
    return [r for r in self.rounds() if any(os.path.exists(self.shown_path(r, p)) for p in ("evaluate", "explore"))]

  def rounds(self) -> list[int]:
    """Round 0 and every round with a directory, in order."""
    rounds = os.path.join(self.path, "rounds")
    return [0] + (sorted(int(d) for d in os.listdir(rounds) if d.isdigit()) if os.path.isdir(rounds) else [])

  def outcomes(self) -> dict:
    """Per-state outcomes of the finished phases: {"evaluate": {round: [0/1 per evaluation state]},
    "explore": {round: [0/1 per episode, tries adjacent]}} (rounds as strings, as JSON keys are)."""
    out = {"evaluate": {}, "explore": {}}
    for r in self.rounds():
      for phase in out:
        if (record := atomic.read_record(self.phase_path(r, phase))) is not None:
          out[phase][str(r)] = record["success"]
    return out

  def demonstrations(self) -> list[dict]:
    return hdf5.read_episodes(self.demos_path)[0]

  def steered_sets(self, before_round: int, only_successful: bool = True) -> list[episodes.EpisodeSet]:
    """Episodes saved from the steering page with the policies of rounds < `before_round` (only the
    successful ones, unless `only_successful` is False)."""
    sets = []
    for q in range(before_round):
      if os.path.exists(path := self.steered_path(q)):
        found = [ep for ep in hdf5.read_episodes(path)[0] if ep.get("success", True) or not only_successful]
        sets.append(episodes.EpisodeSet(found, q, True))
    return sets

  def set_path(self, s: episodes.EpisodeSet) -> str:
    """The file an episode group of the loop's was read from."""
    return self.steered_path(s.source) if s.steered else self.data_path(s.source) if s.source else self.demos_path

  def fit_sets(self, r: int | None = None) -> tuple[list[episodes.EpisodeSet], dict]:
    """The episode groups round r's fit trained on (default r: the last round with a policy), as the
    loop gathers them: the demonstrations, the episodes each round up to r kept, the steered episodes
    the fit took; and the metadata that goes with them (for `data.export`)."""
    last = self.last_round()
    r = last if r is None else r
    if not 0 <= r <= last:
      raise UserError(f"{self.path}: round {r} has no policy yet; its rounds with one are 0..{last}")
    sets = [episodes.EpisodeSet(self.demonstrations(), 0)]
    for q in range(1, r + 1):
      if os.path.exists(self.data_path(q)):
        sets.append(episodes.EpisodeSet(hdf5.read_episodes(self.data_path(q))[0], q))
    sets += self.steered_sets(r, self.config.rounds.steered == "successful")
    meta = dict(
      env_name=self.config.env.task,
      env_kwargs=self.config.env.to_dict(),
      source=f"{self.path}: the data of round {r}'s fit",
      method=self.config.method,
      seed=int(self.config.seed),
      round=r,
    )
    return [s for s in sets if s.episodes], meta

  # -- phases -----------------------------------------------------------------------------------
  def once(
    self,
    r: int,
    name: str,
    compute: Callable[[], tuple[dict, Any]],
    save: Callable[[Any], None] | None = None,
    load: Callable[[dict], Any] | None = None,
  ) -> tuple[dict, Any]:
    """Round r's phase `name` -> (record, value). A finished phase's record is read back and its value
    loaded by `load(record)`; otherwise `compute()` gives both, `save(value)` stores the value, and the
    record (with `round` and `phase`) is written atomically last, so a phase counts as finished only
    once everything it produced is on disk."""
    path = self.phase_path(r, name)
    record = atomic.read_record(path)  # (None: not done, or an empty or torn record)
    if record is not None:
      return record, load(record) if load else None
    record, value = compute()
    record = dict(record, round=r, phase=name)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    if save:
      save(value)
    with faults.site("phase_record"):
      atomic.write_json(path, record)
    return record, value

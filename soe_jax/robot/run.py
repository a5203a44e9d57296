"""Fit and re-fit a robot's policy on dataset files alone: `fit` (round 0 from the demonstrations) and
`refit` (the next round, adding the episodes of a recorded dataset labelled successful).

A workdir holds `config.json`, `spec.json`, and per round r `rounds/<r>/ckpt` (what `serve` loads),
`rounds/<r>/fit.json` (the fit's record: steps, loss curve, episodes by source, the latent's SNR per
dimension over the fit's data, which the server's steering reads) and for r >= 1
`rounds/<r>/data.json` (the recorded dataset and the episodes taken from it). Round r's fit trains on
the demonstrations and every episode rounds 1..r took, read again from their datasets. A re-fit may
override the run's re-fit fields (`rounds`, the simulated runs' names) and keep only some modes'
episodes (`episode_modes`); its fit.json records both, with the `rounds` fields it used. Everything is
checked before anything is written; a fit stopped midway resumes where it was saved (`fit.checkpoint_every`)
when the same command runs again, to the same parameters; keys are fold_in(seed, round, stream).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections import Counter

import ml_collections
import numpy as np
from absl import logging

from soe_jax.analysis.labelled import episode_mode
from soe_jax.data import spec as spec_lib
from soe_jax.data.episodes import EpisodeSet
from soe_jax.explore import steering
from soe_jax.explore.steer import SoeSteer
from soe_jax.policies import policy as policy_lib
from soe_jax.policies.agent import Agent
from soe_jax.robot import config as robot_config
from soe_jax.robot import dataset as dataset_lib
from soe_jax.runtime import atomic
from soe_jax.runtime.errors import UserError
from soe_jax.serve.modes import MODES
from soe_jax.train import checkpoint, normalization
from soe_jax.train import round as round_lib
from soe_jax.train.partial import PartialFit

SELECTIONS = ("all_successes", "first_success")
REFIT_MODES = ("continue", "scratch")
EPISODE_MODES = (*MODES, "recorded")  # a recorded episode's mode (`analysis.labelled.episode_mode`)
_SNR = 2  # the key stream of the latent's SNR (the fit's: `round.FIT`)
SNR_WINDOWS = SoeSteer.snr_windows  # observation histories the stored SNR is measured over (`soe_steer`'s)


def _round_dir(workdir: str, r: int) -> str:
  return os.path.join(workdir, "rounds", str(r))


def _fingerprint(root: str) -> str:
  """What identifies a dataset's content cheaply: its info.json and episode metadata files."""
  h = hashlib.sha1()
  for dirpath, _, files in sorted(os.walk(os.path.join(root, "meta"))):
    for name in sorted(files):
      with open(os.path.join(dirpath, name), "rb") as f:
        h.update(name.encode() + f.read())
  return h.hexdigest()[:12]


def _check(config: ml_collections.ConfigDict) -> None:
  problems = []
  if not config.dataset.path:
    problems.append("dataset.path is empty: the LeRobotDataset of the demonstrations")
  elif not os.path.isdir(config.dataset.path):
    problems.append(f"dataset.path {config.dataset.path!r} is not a directory")
  if config.rounds.select not in SELECTIONS:
    problems.append(f"unknown rounds.select {config.rounds.select!r}; known: {', '.join(SELECTIONS)}")
  if config.rounds.refit not in REFIT_MODES:
    problems.append(f"unknown rounds.refit {config.rounds.refit!r}; known: {', '.join(REFIT_MODES)}")
  if problems:
    raise UserError("; ".join(problems))


def _prepared(config: ml_collections.ConfigDict, progress: bool):
  """(config with the encoder's cameras filled in, spec, policy, demonstrations), all checked."""
  _check(config)
  cameras = dataset_lib.spec_of(config.dataset.path, config.dataset).image_keys
  if cameras and config.policy.encoder.name != "image":
    raise UserError(f"{config.dataset.path} has cameras ({', '.join(cameras)}) and the config's policy reads none: add "
                    "the image preset (--config=configs/robot.py:cpu,image), or name the features it reads in "
                    "dataset.observations")  # fmt: skip
  spec, demos = dataset_lib.read(config.dataset.path, config.dataset, progress=progress)
  config = ml_collections.ConfigDict(config.to_dict())
  if config.policy.encoder.name == "image" and not config.policy.encoder.kwargs.cameras:
    config.policy.encoder.kwargs.cameras = spec.image_keys
  try:
    policy = policy_lib.policy_from_spec(config.policy, spec)
  except ValueError as e:
    raise UserError(str(e)) from None
  longest = max(len(ep["actions"]) for ep in demos)
  if longest > config.data.max_length:
    raise UserError(
      f"{config.dataset.path}: an episode of {longest} steps; data.max_length is {config.data.max_length}"
    )
  return config, spec, policy, demos


def _fit(config, spec, policy, sets, r: int, workdir: str, norm, init_state, progress: bool,
         extra: dict | None = None) -> dict:  # fmt: skip
  """Round r's fit on `sets` (`train.round`, the simulated runs' fit: `init_state` None starts from
  fresh parameters), saved to rounds/<r>/ckpt with its record (and `extra` in it) -> the record."""
  rdir = _round_dir(workdir, r)
  record_path = os.path.join(rdir, "fit.json")
  if os.path.exists(record_path):
    return atomic.read_json(record_path)
  fitter = round_lib.RoundFit(policy, config, spec)
  partial = PartialFit(os.path.join(rdir, "fit_partial"))
  buf, clipped = fitter.data(sets, norm, lambda s: f"round {s.source}'s dataset")
  state, info = fitter.fit(buf, norm, r, partial, init_state, progress=progress)
  fitter.save(os.path.join(rdir, "ckpt"), state, partial)
  snr = None
  if policy.bypass:  # the latent's SNR over this fit's data: the server's steering dimensions
    agent = Agent.from_state(policy, state)
    key = round_lib.round_key(config.seed, r, _SNR)
    snr = [round(float(x), 3) for x in steering.buffer_snr(agent, buf, key, SNR_WINDOWS)]
  record = dict(
    round=r,
    **info,
    num_episodes=sum(len(s.episodes) for s in sets),
    episodes_by_source={str(s.source): len(s.episodes) for s in sets},
    actions_clipped=clipped,
    snr_db=snr,
    **(extra or {}),
  )
  atomic.write_json(record_path, record)  # last: the round is done
  return record


def fit(config: ml_collections.ConfigDict, workdir: str, progress: bool = True) -> dict:
  """Round 0 of a robot's policy from the demonstrations at `config.dataset.path` -> its record."""
  config, spec, policy, demos = _prepared(config, progress)
  saved = os.path.join(workdir, "config.json")
  if os.path.exists(saved) and atomic.read_json(saved) != json.loads(config.to_json()):
    raise UserError(f"{workdir} holds a run of another config ({saved}); use a new --workdir")
  os.makedirs(workdir, exist_ok=True)
  spec_lib.save(workdir, spec)
  atomic.write_json(saved, json.loads(config.to_json()))
  atomic.write_json(os.path.join(workdir, "dataset.json"), dict(path=os.path.abspath(config.dataset.path),
                                                                 fingerprint=_fingerprint(config.dataset.path)))  # fmt: skip
  margin = float(config.policy.normalizer_margin)
  try:
    norm = normalization.fit_normalizer(policy, spec, demos, config.policy.action_range, margin)
  except ValueError as e:
    raise UserError(str(e)) from None
  return _fit(config, spec, policy, [EpisodeSet(demos, 0)], 0, workdir, norm, None, progress)


def last_round(workdir: str) -> int:
  """The last round with a finished fit (-1: none)."""
  r = -1
  while os.path.exists(os.path.join(_round_dir(workdir, r + 1), "fit.json")):
    r += 1
  return r


def select(episodes: list[dict], rule: str, root: str) -> list[dict]:
  """The recorded episodes a re-fit takes: every one labelled successful, or the first success per
  start state (which needs a `start_state` column)."""
  unlabelled = [ep["episode_index"] for ep in episodes if ep["success"] is None]
  if unlabelled:
    raise UserError(f"{root}: episodes {unlabelled[:5]} have no success label (next.success)")
  successes = [ep for ep in episodes if ep["success"]]
  if rule == "all_successes":
    return successes
  if any("start_state" not in ep["columns"] for ep in episodes):
    raise UserError(f"{root}: refit.select=first_success groups tries by start state and needs a `start_state` "
                    "column; the dataset has none (use all_successes)")  # fmt: skip
  seen, out = set(), []
  for ep in successes:
    state = tuple(map(float, ep["columns"]["start_state"][0].reshape(-1)))
    if state not in seen:
      seen.add(state)
      out.append(ep)
  return out


def saved_config(workdir: str) -> ml_collections.ConfigDict:
  """The config `fit` saved in `workdir` (UserError where there is none)."""
  saved = os.path.join(workdir, "config.json")
  if not os.path.exists(saved):
    raise UserError(f"{workdir} has no fitted robot policy ({saved} is missing): run `fit` first")
  return ml_collections.ConfigDict(robot_config.upgrade(atomic.read_json(saved)))


def by_mode(episodes: list[dict], modes: list[str] | None, root: str) -> list[dict]:
  """The recorded episodes of `modes` (None: every one, with a warning when the recording mixes modes,
  since a re-fit would pool, say, SOE's successes with SIME's)."""
  mode_of = [episode_mode(ep["columns"]) for ep in episodes]
  if modes is None:
    if len(set(mode_of)) > 1:
      counts = Counter(mode_of)
      wins = Counter(m for m, ep in zip(mode_of, episodes) if ep["success"])
      each = "; ".join(f"{m}: {n} episodes, {wins[m]} success{'es' if wins[m] != 1 else ''}"
                       for m, n in sorted(counts.items()))  # fmt: skip
      logging.warning("%s mixes modes (%s); the re-fit takes the successes of every one. `refit --episode_modes=MODE` "
                      "keeps one mode's", root, each)  # fmt: skip
    return episodes
  unknown = [m for m in modes if m not in EPISODE_MODES]
  if unknown:
    raise UserError(f"--episode_modes: unknown mode {unknown[0]!r}; known: {', '.join(EPISODE_MODES)}")
  kept = [ep for m, ep in zip(mode_of, episodes) if m in modes]
  if not kept:
    have = ", ".join(f"{m} {n}" for m, n in sorted(Counter(mode_of).items()))
    raise UserError(f"{root}: no episode of mode {', '.join(modes)}; its episodes' modes: {have}")
  return kept


def refit(workdir: str, recorded: str, progress: bool = True, mode: str | None = None,
          overrides: dict | None = None, episode_modes: list[str] | None = None) -> dict:  # fmt: skip
  """The next round of the robot run in `workdir`: the episodes of the LeRobotDataset `recorded`
  (those of `episode_modes`, default all) labelled successful (`rounds.select`) added to the data,
  re-fitted (`rounds.refit`, or `mode`) -> the round's record. `overrides` {"rounds.<field>": value}
  change the run's re-fit fields for this round (recorded in its fit.json). Running it again after
  an interruption continues the same round, with the same overrides. Windows aligned to decisions
  (`rounds.aligned_windows`) need every recorded episode's decisions (`_without_decisions`); without
  them the re-fit draws every window, with a warning."""
  config = saved_config(workdir)
  overrides = {robot_config.upgrade_field(k): v for k, v in (overrides or {}).items()}
  if mode is not None:
    overrides["rounds.refit"] = mode
  fields = sorted(f"rounds.{k}" for k in config.rounds)
  for name in overrides:
    if name not in fields:
      raise UserError(f"{name}: not a re-fit field of the run; its re-fit fields: {', '.join(fields)}")
  config.update_from_flattened_dict(overrides)
  episode_modes = list(episode_modes) if episode_modes else None
  _check(config)
  spec = spec_lib.load(workdir)
  last = last_round(workdir)
  if last < 0:
    raise UserError(f"{workdir}: round 0 has not finished; run `fit` again to finish it")
  r = last + 1
  rdir = _round_dir(workdir, r)
  data_path = os.path.join(rdir, "data.json")
  recorded = os.path.abspath(recorded)
  choices = dict(overrides=overrides, episode_modes=episode_modes)
  if os.path.exists(data_path):
    under_way = atomic.read_json(data_path)
    if under_way["dataset"] != recorded:
      raise UserError(f"{workdir}: round {r} is under way with {under_way['dataset']}; finish it first")
    was = {k: under_way.get(k, {} if k == "overrides" else None) for k in choices}
    was["overrides"] = {robot_config.upgrade_field(k): v for k, v in was["overrides"].items()}
    if was != choices:
      raise UserError(f"{workdir}: round {r} is under way with {was}; finish it with the same (now {choices})")
  _, demos = dataset_lib.read(config.dataset.path, config.dataset, progress=progress)
  sets = [EpisodeSet(demos, 0)]
  for q in range(1, r):
    taken = atomic.read_json(os.path.join(_round_dir(workdir, q), "data.json"))
    _, eps = dataset_lib.read(taken["dataset"], config.dataset, taken["episodes"], progress)
    sets.append(EpisodeSet(eps, q))
  rec_spec, episodes = dataset_lib.read(recorded, config.dataset, progress=progress)
  if rec_spec.to_dict() != spec.to_dict():
    raise UserError(f"{recorded}: its spec differs from the policy's ({os.path.join(workdir, spec_lib.SPEC_FILE)})")
  taken = select(by_mode(episodes, episode_modes, recorded), config.rounds.select, recorded)
  if not taken:
    raise UserError(f"{recorded}: none of its {len(episodes)} episodes is labelled successful; nothing to add")
  loaded = checkpoint.load(os.path.join(_round_dir(workdir, last), "ckpt"))
  os.makedirs(rdir, exist_ok=True)
  atomic.write_json(data_path, dict(dataset=recorded, fingerprint=_fingerprint(recorded), select=config.rounds.select,
                                    recorded=len(episodes), episodes=[ep["episode_index"] for ep in taken],
                                    **choices))  # fmt: skip
  sets.append(EpisodeSet(taken, r))
  if config.rounds.aligned_windows and (without := _without_decisions(sets[1:], loaded.policy.n_action_steps)):
    logging.warning("%d recorded episodes (%s) have no decisions every %d steps from the first (the `decision` "
                    "feature): this re-fit draws every window, not only those at decisions",
                    len(without), ", ".join(without[:3]) + (", ..." if len(without) > 3 else ""),
                    loaded.policy.n_action_steps)  # fmt: skip
    config.rounds.aligned_windows = False
  norm = loaded.state.normalizer  # the statistics stay those of the demonstrations
  extra = dict(choices, rounds=config.rounds.to_dict())
  init_state = loaded.state if config.rounds.refit == "continue" else None
  return _fit(config, spec, loaded.policy, sets, r, workdir, norm, init_state, progress, extra)


def _without_decisions(sets: list[EpisodeSet], n_action_steps: int) -> list[str]:
  """The recorded episodes whose windows cannot be aligned to decisions ('round 1 episode 4', ...):
  those without the recorder's `decision` feature, whose decisions are not every `n_action_steps`
  steps from the first (a client that executed part of a chunk), or where the frames from one decision
  to the next came from more than one request (`request_key`: a client with real-time chunks, which
  executes an earlier chunk's actions at a decision and aggregates overlapping chunks)."""
  return [f"round {s.source} episode {ep['episode_index']}" for s in sets for ep in s.episodes
          if not _at_decisions(ep, n_action_steps)]  # fmt: skip


def _at_decisions(ep: dict, n_action_steps: int) -> bool:
  """Whether a recorded episode's decisions are every `n_action_steps` frames from the first, each
  span between two from one request (`_without_decisions`)."""
  decision = ep["columns"].get("decision")
  every = np.arange(len(ep["actions"])) % n_action_steps == 0
  if decision is None or not np.array_equal(np.asarray(decision), every.astype(np.asarray(decision).dtype)):
    return False
  key = ep["columns"].get("request_key")
  return key is None or all(
    len(np.unique(np.asarray(key)[i : i + n_action_steps, 3])) == 1 for i in np.flatnonzero(every)
  )

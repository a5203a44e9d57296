"""Everything about a config that can be checked before any work or any file is written: names,
counts and rates, the horizons' relation, and the demonstration file. `check(config)` raises
`UserError` with one line per problem."""

from __future__ import annotations

import importlib.util

import ml_collections
import numpy as np

from soe_jax.data import hdf5
from soe_jax.envs import backends, controller, observations
from soe_jax.envs import registry as env_registry
from soe_jax.experiment import schema, select
from soe_jax.experts import registry as expert_registry
from soe_jax.explore import registry as strategy_registry
from soe_jax.policies import frames
from soe_jax.policies import registry as policy_registry
from soe_jax.render import choice as render_choice
from soe_jax.runtime.errors import UserError


def _get(config, field: str):
  for part in field.split("."):
    config = config[part]
  return config


def problems(config: ml_collections.ConfigDict) -> list[str]:
  """What is wrong with `config`, one line each (empty if nothing)."""
  out = []

  def name(check, *args):
    try:
      check(*args)
    except ValueError as e:
      out.append(str(e))

  name(env_registry.TASKS.check, config.env.task)
  if config.env.backend != "auto":
    name(backends.resolve_backend, config.env.backend)
  name(backends.check_mjx_impl, config.env.mjx_impl, config.env.backend)
  name(backends.parse_settings, config.env.mjx_settings, {})
  if config.env.obs_mode == "image" or config.env.renderer not in ("auto", *render_choice.RENDERERS):
    name(render_choice.resolve, config.env.renderer)
  name(controller.action_size, config.env.action_mode)
  name(policy_registry.HEADS.check, config.policy.head.name)
  name(policy_registry.ENCODERS.check, config.policy.encoder.name)
  name(strategy_registry.check_settings, config.explore.strategy.name, config.explore.strategy.kwargs)
  name(select.SELECTIONS.check, config.rounds.select)
  if config.rounds.refit not in schema.REFITS:
    out.append(f"unknown re-fit mode {config.rounds.refit!r}; known: {', '.join(schema.REFITS)}")
  if config.rounds.refit_ema not in schema.REFIT_EMA:
    out.append(f"unknown rounds.refit_ema {config.rounds.refit_ema!r}; known: {', '.join(schema.REFIT_EMA)}")
  if config.policy.action_range not in schema.ACTION_RANGES:
    known = ", ".join(schema.ACTION_RANGES)
    out.append(f"unknown policy.action_range {config.policy.action_range!r}; known: {known}")
  elif config.policy.action_frame not in frames.FRAMES:
    out.append(f"unknown policy.action_frame {config.policy.action_frame!r}; known: {', '.join(frames.FRAMES)}")
  elif config.policy.action_frame == "chunk_relative" and (
    config.policy.action_range == "workspace" or config.env.action_mode != "absolute"
  ):
    out.append("policy.action_frame=chunk_relative takes absolute actions (env.action_mode=absolute) and normalises the "
               "relative displacements over their range: set policy.action_range=demonstrations (the workspace box "
               "bounds absolute positions)")  # fmt: skip
  elif config.policy.action_range == "workspace" and config.env.action_mode == "absolute" and not out:
    if env_registry.TASKS.factory(config.env.task).workspace is None:
      out.append(f"task {config.env.task!r} has no workspace box; use policy.action_range=demonstrations")
  if config.rounds.new_data not in schema.NEW_DATA:
    out.append(f"unknown rounds.new_data {config.rounds.new_data!r}; known: {', '.join(schema.NEW_DATA)}")
  if config.rounds.steered not in schema.STEERED:
    out.append(f"unknown rounds.steered {config.rounds.steered!r}; known: {', '.join(schema.STEERED)}")
  out += [f"{f} must be at least 1, got {_get(config, f)}" for f in schema.POSITIVE if _get(config, f) < 1]
  out += [f"{f} must be >= 0, got {_get(config, f)}" for f in schema.NON_NEGATIVE if _get(config, f) < 0]
  if not 0 <= config.rounds.demo_fraction < 1:
    out.append(f"rounds.demo_fraction must be in [0, 1), got {config.rounds.demo_fraction}")
  if not 0 < config.policy.bypass.batch_fraction <= 1:
    out.append(f"policy.bypass.batch_fraction must be in (0, 1], got {config.policy.bypass.batch_fraction}")
  if config.fit.lr <= 0:
    out.append(f"fit.lr must be > 0, got {config.fit.lr}")
  p = config.policy
  if p.n_action_steps > p.horizon - p.n_obs_steps + 1:
    out.append(
      f"policy.n_action_steps ({p.n_action_steps}) must be at most policy.horizon - policy.n_obs_steps + 1 "
      f"({p.horizon - p.n_obs_steps + 1}): the executed actions lie inside the predicted chunk"
    )
  out += _images(config)
  if config.data.capacity < config.data.num_demos:
    out.append(f"data.capacity ({config.data.capacity}) must hold data.num_demos ({config.data.num_demos})")
  if config.log.wandb and importlib.util.find_spec("wandb") is None:
    out.append("log.wandb needs wandb, which is not installed: pip install -e '.[wandb]'")
  style = config.data.demo_style
  if style not in expert_registry.STYLES:
    out.append(f"unknown data.demo_style {style!r}; known: {', '.join(expert_registry.STYLES)}")
  elif style != "scripted" and config.data.hdf5_path:
    out.append(f"data.demo_style={style} is a demonstrator's; with data.hdf5_path the file's demonstrations are used")
  elif style != "scripted" and config.env.task in expert_registry.expert_names():
    if config.env.task not in expert_registry.VARIED.names():
      out.append(f"task {config.env.task!r} has no {style} demonstrator; tasks with one: "
                 f"{', '.join(expert_registry.VARIED.names())}")  # fmt: skip
  if config.data.hdf5_path and not out:
    out += _demonstration_file(config)
  return out


def _images(config) -> list[str]:
  """The observation mode is known, and an image encoder reads images the task draws, in crops that fit."""
  mode, enc = config.env.obs_mode, config.policy.encoder
  if mode not in observations.OBS_MODES:
    return [f"unknown env.obs_mode {mode!r}; known observation modes: {', '.join(observations.OBS_MODES)}"]
  if enc.name != "image":
    return []
  out = []
  if mode != "image":
    out.append("policy.encoder 'image' reads camera images: set env.obs_mode='image' (the `image` preset does)")
  drawn = env_registry.image_keys(config.env.task) if config.env.task in env_registry.env_names() else ()
  cameras = list(enc.kwargs.get("cameras", drawn))
  unknown = [c for c in cameras if c not in drawn]
  if unknown and drawn:
    out.append(
      f"unknown camera images {', '.join(map(repr, unknown))}; the {config.env.task} task draws {', '.join(drawn)}"
    )
  crop = enc.kwargs.get("crop_size", 76)
  if not 0 < crop <= config.env.image_size:
    out.append(f"policy.encoder.kwargs.crop_size ({crop}) must be in 1..env.image_size ({config.env.image_size})")
  if config.data.image_frames < 1:
    out.append("data.image_frames must be at least 1 for an image policy (the frames of images the buffer holds)")
  return out


def _demonstration_file(config) -> list[str]:
  """The file `data.hdf5_path` is readable, holds enough episodes, with the task's keys and sizes."""
  path = config.data.hdf5_path
  try:
    episodes, _ = hdf5.read_episodes(path, filter_key=config.data.filter_key)
  except (OSError, ValueError) as e:
    return [str(e)]
  if len(episodes) < config.data.num_demos:
    return [f"{path} holds {len(episodes)} episodes; data.num_demos asks for {config.data.num_demos}"]
  task = config.env.task
  sizes = observations.policy_obs_sizes(env_registry.TASKS.factory(task).object_dim, env_registry.num_robots(task))
  action = env_registry.action_size(config.env.task, config.env.action_mode)
  for i, ep in enumerate(episodes[: config.data.num_demos]):
    for key, size in sizes.items():
      got = np.shape(ep["obs"].get(key, ()))
      if key not in ep["obs"] or len(got) != 2 or got[1] != size:
        return [f"{path}: episode {i} obs {key!r} has shape {got if key in ep['obs'] else 'missing'}, the task "
                f"{config.env.task!r} needs (T, {size})"]  # fmt: skip
    if np.shape(ep["actions"])[-1:] != (action,) or len(ep["actions"]) != len(ep["obs"]["robot0_eef_pos"]):
      return [f"{path}: episode {i} actions have shape {np.shape(ep['actions'])}, need (T, {action}) for its T frames"]
    if len(ep["actions"]) > config.data.max_length:
      return [f"{path}: episode {i} has {len(ep['actions'])} steps, more than data.max_length={config.data.max_length}"]
  return []


def check(config: ml_collections.ConfigDict) -> None:
  """Raise `UserError` listing every problem of `config`."""
  found = problems(config)
  if found:
    raise UserError(found[0] if len(found) == 1 else "the config has problems:\n  " + "\n  ".join(found))

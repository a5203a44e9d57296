"""One person steering one episode of a finished run's policy in its simulated task.

The session holds the simulator state (one environment, C engine), the observation history and the
episode so far. `proposals(dim)` decodes proposals along one effective latent dimension and keeps a
diverse few (farthest point sampling); `execute(id)` runs the chosen one open loop. `save()` appends
the finished episode, marked as steered and with its success, to `data/steered_round_<R>.hdf5` in the
run; the next round's fit takes the successful ones (all of them with `rounds.steered="all"`). Every
request is checked first (unknown proposal id, wrong round, unfinished or finished episode) and a bad
one raises `SteeringError` without changing anything.
"""

from __future__ import annotations

import dataclasses
import io
import os
import threading

import jax
import jax.numpy as jnp
import matplotlib.image
import mujoco
import numpy as np

from soe_jax.data import hdf5
from soe_jax.data.episodes import EpisodeSet, build_buffer
from soe_jax.envs import observations, panda
from soe_jax.envs import registry as env_registry
from soe_jax.experiment import task
from soe_jax.experiment.rundir import RunDir
from soe_jax.explore import registry as strategy_registry
from soe_jax.policies import agent as agent_lib
from soe_jax.render.pool import Renderer
from soe_jax.runtime.errors import UserError
from soe_jax.train import checkpoint

IMAGE_SIZE = 384
VIEWS = ("agentview", panda.EYE_IN_HAND)  # the page's views: the scene, and the wrist camera's


class SteeringError(ValueError):
  """A request the session refuses; nothing was changed."""


class SteeringSession:
  def __init__(self, workdir: str, round_: int | None = None, seed: int = 0, image_size: int = IMAGE_SIZE):
    self.run = RunDir.open(workdir)
    self.workdir, self.config = self.run.path, self.run.config
    self.round = self.run.last_round() if round_ is None else int(round_)
    if not self.run.has_checkpoint(self.round):
      raise UserError(
        f"{self.workdir}: round {self.round} has no policy yet; the last with one is {self.run.last_round()}"
      )
    loaded = checkpoint.load(self.run.checkpoint_dir(self.round), task.spec(self.config))
    self.policy, self.agent = loaded.policy, loaded.agent
    env_config = self.config.env.copy_and_resolve_references()
    env_config.backend = "mujoco"  # one environment, stepped and rendered in the C engine
    self.env = env_registry.env_from_config(env_config)
    self.lock = threading.Lock()
    self._step = jax.jit(jax.vmap(self.env.step))
    self._reset = jax.jit(jax.vmap(self.env.reset))
    self.steer = strategy_registry.steering_strategy(self.config.explore.strategy, self.env)
    # One program for every dimension (the dimension is an argument, not a constant).
    self._candidates = jax.jit(lambda agent, hist, key, dim: self.steer.candidates(agent, hist, key, (dim,)))
    buf = build_buffer(self.config, self.policy, [EpisodeSet(self.run.demonstrations(), 0)], self.env)
    # The dimensions as the strategy prepares them for a round, every effective one offered to a person
    # (`max_dims` caps only the unattended chooser's).
    prepared, extra = dataclasses.replace(self.steer, max_dims=0).prepare(self.agent, buf, jax.random.key(0))
    self.snr = np.asarray(extra["snr_db"])
    self.none_above_threshold = not prepared.dims
    # With no dimension above the threshold: the strongest (the page says it carries little signal).
    self.dims = prepared.dims or (int(np.argmax(self.snr)),)
    self.image_size = image_size
    # The process that draws (started on first use): rendering stays out of this process, which compiles XLA.
    self.frames = Renderer(self.env.mj_model, VIEWS, image_size, processes=1)
    self.data = mujoco.MjData(self.env.mj_model)
    self.saved = 0
    self.last_saved = None  # {"success": bool, "used": bool} of the episode saved last
    self.used_in_fit = self.config.rounds.steered  # successful | all
    self.reset(seed)

  def warm(self) -> None:
    """Compile the proposal program and render the first frame, so the page's first requests are
    quick. Changes nothing."""
    self._candidates(self.agent, self.hist, self.key, self.dims[0])[0].block_until_ready()
    self.image_png()

  # -- state ------------------------------------------------------------------------------------
  def reset(self, seed: int = 0) -> dict:
    self.seed = int(seed)
    self.key = jax.random.fold_in(jax.random.key(int(self.config.seed) + 7), self.seed)
    self.state = self._reset(jax.random.split(jax.random.key(self.seed), 1))
    self.hist = agent_lib.initial_history(self._policy_input(), self.policy.n_obs_steps)
    self.episode = dict(obs=[], next_obs=[], actions=[], states=[])
    self.eef = [self._hands()]
    self.success = False
    self.finished = False
    self.decision = 0
    self.proposal_set = None  # (dim, candidates (C, Ta, A), token)
    return self.view()

  def _policy_input(self):
    return observations.policy_input(self.state.obs, self.policy.image_keys, self.policy.lowdim_keys)

  def _check_round(self, round_) -> None:
    if round_ is not None and int(round_) != self.round:
      raise SteeringError(f"this page steers round {self.round}, not round {round_}; reload the page")

  def proposals(self, dim: int, round_=None) -> dict:
    self._check_round(round_)
    if self.finished:
      raise SteeringError("the episode is over: reset it or save it")
    try:
      dim = int(dim)
    except (TypeError, ValueError):
      raise SteeringError(f"dimension must be an integer, got {dim!r}") from None
    if dim not in self.dims:
      raise SteeringError(f"dimension {dim} is not an effective dimension; choose one of {list(self.dims)}")
    key = jax.random.fold_in(self.key, 1000 * self.decision + dim)
    cands, _ = self._candidates(self.agent, self.hist, key, dim)
    self.proposal_set = (dim, np.asarray(cands[0]), f"{self.decision}-{dim}")
    return self.view()

  def execute(self, proposal_id, round_=None) -> dict:
    """Run proposal `proposal_id` ('<decision>-<dim>-<index>') of the current set open loop."""
    self._check_round(round_)
    if self.finished:
      raise SteeringError("the episode is over: reset it or save it")
    if self.proposal_set is None:
      raise SteeringError("no proposals yet: choose a dimension first")
    dim, cands, token = self.proposal_set
    prefix, _, index = str(proposal_id).rpartition("-")
    if prefix != token or not index.isdigit() or int(index) >= len(cands):
      raise SteeringError(
        f"unknown proposal {proposal_id!r}; the current ones are {token}-0 .. {token}-{len(cands) - 1}"
      )
    for action in cands[int(index)]:
      self.episode["obs"].append(np.asarray(observations.policy_obs(self.state.obs)[0]))
      self.episode["states"].append(
        self.env.physics.sim_state_float64(self.env.physics.sim_state(self.state.pipeline_state))[0]
      )
      self.episode["actions"].append(np.asarray(action))
      self.state = self._step(self.state, jnp.asarray(action)[None])
      self.hist = agent_lib.push_history(self.hist, self._policy_input())
      self.episode["next_obs"].append(np.asarray(observations.policy_obs(self.state.obs)[0]))
      self.eef.append(self._hands())
      if bool(self.state.metrics["success"][0] > 0):
        self.success = True
        break
    self.decision += 1
    self.proposal_set = None
    self.finished = self.success or len(self.episode["actions"]) >= self.env.episode_length
    return self.view()

  def finish(self) -> dict:
    self.finished = True
    self.proposal_set = None
    return self.view()

  def save(self, round_=None) -> dict:
    """Append the finished episode, marked as steered and with its success, to the run's data for the
    next round (whose fit takes only the successful ones unless `rounds.steered` is "all"); then reset."""
    self._check_round(round_)
    if not self.episode["actions"]:
      raise SteeringError("nothing to save: execute at least one proposal first")
    if not self.finished:
      raise SteeringError(
        "the episode is not over: it ends with success or at the step limit, or press 'finish' to end it here"
      )
    path = self.run.steered_path(self.round)
    episodes = hdf5.read_episodes(path)[0] if os.path.exists(path) else []
    episodes.append(
      dict(
        obs=observations.split_policy_obs(np.stack(self.episode["obs"]), self.env.num_robots),
        next_obs=observations.split_policy_obs(np.stack(self.episode["next_obs"]), self.env.num_robots),
        actions=np.stack(self.episode["actions"]),
        states=np.stack(self.episode["states"]),
        success=self.success,
      )
    )
    hdf5.write_episodes(
      path, episodes, dict(env_name=self.env.name, source=f"steered with round {self.round}", steered=True)
    )
    self.saved = len(episodes)
    self.last_saved = dict(success=self.success, used=self.success or self.used_in_fit == "all")
    return self.reset(self.seed + 1)

  def close(self) -> None:
    """End the process that draws the frames."""
    self.frames.close()

  # -- what the page shows ----------------------------------------------------------------------
  def _camera(self):
    mujoco.mj_forward(self.env.mj_model, self.data)
    cam = self.env.mj_model.camera("agentview").id
    return (
      self.data.cam_xpos[cam].copy(),
      self.data.cam_xmat[cam].reshape(3, 3).copy(),
      float(self.env.mj_model.cam_fovy[cam]),
    )

  def _hands(self) -> np.ndarray:
    """Every arm's grip-site position now, (R, 3)."""
    return np.stack([np.asarray(self.state.obs[f"robot{k}_eef_pos"][0]) for k in range(self.env.num_robots)])

  def project(self, points: np.ndarray) -> list[list[float]]:
    """World points (N, 3) -> pixel coordinates in the rendered image (x right, y down)."""
    pos, rot, fovy = self._camera()
    size = self.image_size
    c = (np.asarray(points) - pos) @ rot  # camera frame: x right, y up, looking along -z
    f = 0.5 * size / np.tan(np.deg2rad(fovy) / 2)
    return [[float(size / 2 + f * x / -z), float(size / 2 - f * y / -z)] for x, y, z in c]

  def image_png(self, view: str = "agentview") -> bytes:
    """The scene now from one of `VIEWS` (the fixed camera by default), as PNG."""
    if view not in VIEWS:
      raise SteeringError(f"unknown view {view!r}; the views: {', '.join(VIEWS)}")
    image = self.frames.render(self.state.pipeline_state.qpos[0])[view]
    buf = io.BytesIO()
    matplotlib.image.imsave(buf, image, format="png")
    return buf.getvalue()

  def view(self) -> dict:
    props = []
    if self.proposal_set is not None:
      dim, cands, token = self.proposal_set
      arms = lambda c: np.swapaxes(observations.action_positions(c, self.env.num_robots), 0, 1)  # (R, Ta, 3)
      props = [dict(id=f"{token}-{i}", paths=[self.project(p) for p in arms(c)]) for i, c in enumerate(cands)]
    return dict(
      round=self.round,
      step=len(self.episode["actions"]),
      episode_length=self.env.episode_length,
      success=self.success,
      finished=self.finished,
      saved=self.saved,
      seed=self.seed,
      dims=[dict(dim=int(d), snr_db=round(float(self.snr[d]), 2)) for d in self.dims],
      snr=[dict(dim=i, snr_db=round(float(x), 2), offered=i in self.dims) for i, x in enumerate(self.snr)],
      threshold_db=float(self.steer.threshold_db),
      none_above_threshold=self.none_above_threshold,
      steps_per_proposal=int(self.policy.n_action_steps),
      last_saved=self.last_saved,
      used_in_fit=self.used_in_fit,
      chosen_dim=None if self.proposal_set is None else int(self.proposal_set[0]),
      proposals=props,
      paths=[self.project(p) for p in np.swapaxes(np.stack(self.eef), 0, 1)],  # each arm's, robot0 first
    )

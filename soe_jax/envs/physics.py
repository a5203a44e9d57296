"""Two physics backends behind one interface: `mjx` (accelerators) and `mujoco` (CPU, C engine).

A backend turns joint-space controls into the next physics state over `nsubsteps` substeps with the
control held constant. Everything around it (reset sampling, IK, observations, success) is shared JAX
code, so the same task runs on either.

- `MjxBackend`: the substeps are a `lax.scan` of `mjx.step`; the state is an `mjx.Data` (float32).
- `MujocoBackend`: the whole batch's substeps run in MuJoCo's C engine, multi-threaded through
  `mujoco.rollout`, reached from the compiled program through `jax.pure_callback`. MuJoCo's full
  physics state is float64; it is carried through JAX bit-exactly as a uint32 view of its bytes, so
  states stay ordinary pytrees (auto-reset with `where`, checkpoints, determinism) without x64.
"""

from __future__ import annotations

import copy
import logging
import os
import threading
import time

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import rollout

from soe_jax.envs.backends import BACKENDS, resolve_backend, resolve_mjx_impl


@struct.dataclass
class PhysicsState:
  """What the shared JAX code reads (float32 qpos, qvel) plus the backend's own state in `raw`."""

  qpos: jax.Array  # (nq,)
  qvel: jax.Array  # (nv,)
  raw: object  # mjx.Data, or (2 * nstate,) uint32 bytes of MuJoCo's float64 full physics state


def make_backend(name: str, model: mujoco.MjModel, nsubsteps: int, mjx_options: dict | None = None):
  """Backend `name` (`auto`, `mujoco` or `mjx`) for `model`; `mjx_options` are `MjxBackend`'s keyword
  arguments, used only when the backend is MJX."""
  name = resolve_backend(name)
  return BACKENDS.make(name, model, nsubsteps, **((mjx_options or {}) if name == "mjx" else {}))


# MuJoCo Warp's overflow bits that mean lost contacts or constraints (solver iteration limits are not).
WARP_LOSSES = {
  1: "constraints (njmax)",
  2: "nonzeros (njmax_nnz)",
  4: "contacts (broadphase)",
  8: "contacts (narrowphase)",
  16: "CCD contacts",
  128: "active DOFs (nvmax)",
  256: "EPA horizon",
}


class MjxBackend:
  """Substeps as a `lax.scan` of `mjx.step`, vmappable; `impl` is MJX's implementation (`jax`, `warp`
  or `auto`).

  `settings` override the model's solver options for MJX alone (`iterations`, `ls_iterations`,
  `cone`: the accelerator's scene, `ManipulationEnv.mjx_settings`); the C engine keeps the scene's.
  MuJoCo Warp preallocates its contacts for all environments together and its constraints per
  environment: `contacts` per environment times `max_batch` environments, and `constraints` rows per
  environment; `check(state)` raises if a step ran out of either (Warp drops what does not fit).
  """

  name = "mjx"

  def __init__(
    self,
    model: mujoco.MjModel,
    nsubsteps: int,
    impl: str = "jax",
    settings: dict | None = None,
    contacts: int = 32,
    constraints: int = 256,
    max_batch: int = 8192,
  ):
    from mujoco import mjx  # imported lazily: it is heavy and only this backend needs it

    self._mjx = mjx
    self.model = model
    self.nsubsteps = nsubsteps
    self.impl = resolve_mjx_impl(impl)
    self.settings = dict(settings or {})
    self.sim_model = apply_settings(model, self.settings)
    self.max_batch, self.contacts, self.constraints = int(max_batch), int(contacts), int(constraints)
    self.mjx_model = mjx.put_model(self.sim_model, impl=self.impl)
    if self.impl == "warp":
      import warp  # here, not at the top: the optional `gpu` extra's (MuJoCo Warp)

      warp.config.quiet = True  # fewer lines per kernel module loaded
      # Warp prints a line each step that reaches an iteration cap; only losses are worth one.
      self.mjx_model = self.mjx_model.tree_replace({"opt._impl.warn_overflow": sum(WARP_LOSSES)})
      self._template = mjx.make_data(
        self.sim_model, impl="warp", naconmax=self.contacts * self.max_batch, njmax=self.constraints
      )
    else:
      self._template = mjx.make_data(self.mjx_model)

  def init(self, qpos: jax.Array, qvel: jax.Array) -> PhysicsState:
    d = self._template.replace(qpos=qpos, qvel=qvel)
    d = self._mjx.forward(self.mjx_model, d)
    return PhysicsState(qpos=d.qpos, qvel=d.qvel, raw=d)

  def step(self, state: PhysicsState, ctrl: jax.Array) -> PhysicsState:
    d = state.raw.replace(ctrl=ctrl)

    def substep(d, _):
      return self._mjx.step(self.mjx_model, d), None

    d, _ = jax.lax.scan(substep, d, None, length=self.nsubsteps)
    return PhysicsState(qpos=d.qpos, qvel=d.qvel, raw=d)

  def where(self, done: jax.Array, reset: PhysicsState, state: PhysicsState) -> PhysicsState:
    """`reset` where `done`, else `state`, for one environment (inside `vmap`: `done` is a scalar);
    Warp's buffers shared by all environments stay `state`'s."""
    return PhysicsState(
      qpos=jnp.where(done, reset.qpos, state.qpos),
      qvel=jnp.where(done, reset.qvel, state.qvel),
      raw=state.raw.where(done, reset.raw),
    )

  def check(self, state: PhysicsState) -> None:
    """Raise if any environment of a batched state ran out of Warp's preallocated contacts or
    constraints (Warp's overflow bits are sticky); nothing to check for MJX-JAX."""
    if self.impl != "warp":
      return
    batch = int(np.prod(state.qpos.shape[:-1]))
    if batch > self.max_batch:
      raise ValueError(f"{batch} environments in one batch, more than env.mjx_max_batch={self.max_batch}")
    bits = np.bitwise_or.reduce(np.asarray(jax.device_get(state.raw._impl.overflow)).reshape(-1))
    lost = [what for bit, what in WARP_LOSSES.items() if bits & bit]
    if lost:
      raise RuntimeError(
        f"MuJoCo Warp ran out of preallocated {', '.join(lost)} (contacts {self.contacts} per environment for "
        f"{self.max_batch} environments, constraints {self.constraints} per environment); raise the task's "
        "mjx_contacts / mjx_constraints"
      )

  def sim_state(self, state: PhysicsState) -> jax.Array:
    """What a rollout records for robomimic's `states`: [time, qpos, qvel] (..., 1 + nq + nv), in MJX's
    own float32."""
    d = state.raw
    return jnp.concatenate([d.time[..., None], d.qpos, d.qvel], -1)

  def sim_state_float64(self, recorded) -> np.ndarray:
    """Recorded `sim_state`s on the host -> (..., 1 + nq + nv) float64 (exactly MJX's values)."""
    return np.asarray(recorded, np.float64)


# MuJoCo's friction cones by the names `env.mjx_settings` takes (`backends.CONES`).
CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}


def apply_settings(model: mujoco.MjModel, settings: dict) -> mujoco.MjModel:
  """A copy of `model` with the solver options `settings` names replaced (`SETTINGS`)."""
  m = copy.deepcopy(model)
  for k, v in settings.items():
    setattr(m.opt, k, CONES[v] if k == "cone" else v)
  return m


class MujocoBackend:
  """The C engine, batched and multi-threaded with `mujoco.rollout`, behind `jax.pure_callback`."""

  name = "mujoco"

  def __init__(self, model: mujoco.MjModel, nsubsteps: int, nthread: int | None = None):
    self.model = model
    self.nsubsteps = nsubsteps
    self.nthread = nthread or os.cpu_count() or 1
    self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
    self.nstate = mujoco.mj_stateSize(model, self.spec)
    self._datas = [mujoco.MjData(model) for _ in range(self.nthread)]
    self._rollout = rollout.Rollout(nthread=self.nthread)
    self._lock = threading.Lock()  # one rollout at a time: the thread pool and datas are shared
    template = np.empty(self.nstate, np.float64)
    mujoco.mj_getState(model, mujoco.MjData(model), template, self.spec)
    self._template = template
    # mjSTATE_FULLPHYSICS starts with time, then qpos, then qvel.
    self._qpos = slice(1, 1 + model.nq)
    self._qvel = slice(1 + model.nq, 1 + model.nq + model.nv)
    self.physics_seconds = 0.0  # time spent inside the C engine, for benchmarks
    self.callback_seconds = 0.0  # time spent inside the step callback, conversion included
    # MuJoCo resets an environment whose accelerations blow up and only logs it to MUJOCO_LOG.TXT;
    # count those events so that they are reported instead of passing silently.
    self.instabilities = 0

  # -- host side ------------------------------------------------------------------------------
  def _host_init(self, qpos, qvel):
    qpos, qvel = np.asarray(qpos), np.asarray(qvel)
    batch = qpos.shape[:-1]
    s = np.broadcast_to(self._template, batch + (self.nstate,)).copy()
    s[..., self._qpos] = qpos
    s[..., self._qvel] = qvel
    return s.view(np.uint32)

  def _host_step(self, bits, ctrl):
    t0 = time.perf_counter()
    bits, ctrl = np.asarray(bits), np.asarray(ctrl)
    batch = bits.shape[:-1]
    s0 = np.ascontiguousarray(bits.reshape(-1, 2 * self.nstate)).view(np.float64)
    n = s0.shape[0]
    u = np.repeat(ctrl.reshape(n, 1, -1).astype(np.float64), self.nsubsteps, axis=1)
    out = np.empty((n, self.nsubsteps, self.nstate), np.float64)
    warm = np.zeros((n, self.model.nv), np.float64)  # a fixed warm start keeps results thread-independent
    t1 = time.perf_counter()
    with self._lock:
      self._rollout.rollout(
        [self.model] * n,
        self._datas,
        s0,
        u,
        initial_warmstart=warm,
        state=out,
        nstep=self.nsubsteps,
        skip_checks=True,
        sensordata=np.empty((n, self.nsubsteps, 0)),
        chunk_size=max(1, n // (4 * self.nthread)),
      )
    t2 = time.perf_counter()
    self._check_instabilities()
    s1 = np.ascontiguousarray(out[:, -1])
    result = (
      s1.view(np.uint32).reshape(batch + (2 * self.nstate,)),
      s1[:, self._qpos].astype(np.float32).reshape(batch + (self.model.nq,)),
      s1[:, self._qvel].astype(np.float32).reshape(batch + (self.model.nv,)),
    )
    self.physics_seconds += t2 - t1
    self.callback_seconds += time.perf_counter() - t0
    return result

  def _check_instabilities(self):
    bad = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQPOS)
    total = sum(int(d.warning[w].number) for d in self._datas for w in bad)
    if total > self.instabilities:
      logging.warning(
        "MuJoCo: %d physics instabilities (NaN/Inf or huge values) so far; the affected "
        "environments were reset by the engine",
        total,
      )
      self.instabilities = total

  # -- traced side ----------------------------------------------------------------------------
  def init(self, qpos: jax.Array, qvel: jax.Array) -> PhysicsState:
    shape = jax.ShapeDtypeStruct(qpos.shape[:-1] + (2 * self.nstate,), jnp.uint32)
    bits = jax.pure_callback(self._host_init, shape, qpos, qvel, vmap_method="broadcast_all")
    return PhysicsState(qpos=qpos, qvel=qvel, raw=bits)

  def step(self, state: PhysicsState, ctrl: jax.Array) -> PhysicsState:
    batch = state.raw.shape[:-1]
    shapes = (
      jax.ShapeDtypeStruct(batch + (2 * self.nstate,), jnp.uint32),
      jax.ShapeDtypeStruct(batch + (self.model.nq,), jnp.float32),
      jax.ShapeDtypeStruct(batch + (self.model.nv,), jnp.float32),
    )
    bits, qpos, qvel = jax.pure_callback(
      self._host_step, shapes, state.raw, ctrl.astype(jnp.float32), vmap_method="broadcast_all"
    )
    return PhysicsState(qpos=qpos, qvel=qvel, raw=bits)

  def where(self, done: jax.Array, reset: PhysicsState, state: PhysicsState) -> PhysicsState:
    """`reset` where `done`, else `state`, for one environment (inside `vmap`)."""
    return jax.tree.map(lambda r, s: jnp.where(done, r, s), reset, state)

  def check(self, state: PhysicsState) -> None:
    """Nothing to check: the C engine allocates contacts as it needs them."""

  def sim_state(self, state: PhysicsState) -> jax.Array:
    """What a rollout records for robomimic's `states`: the engine's float64 [time, qpos, qvel], the
    start of mjSTATE_FULLPHYSICS, as its uint32 bytes (..., 2 (1 + nq + nv))."""
    return state.raw[..., : 2 * (1 + self.model.nq + self.model.nv)]

  def sim_state_float64(self, recorded) -> np.ndarray:
    """Recorded `sim_state`s on the host -> (..., 1 + nq + nv) float64, bit for bit the engine's."""
    return np.ascontiguousarray(recorded).view(np.float64)

  def float64_state(self, state: PhysicsState) -> np.ndarray:
    """The exact MuJoCo state on the host, (..., nstate) float64."""
    bits = np.ascontiguousarray(jax.device_get(state.raw))
    return bits.view(np.float64)

"""How faithful the exploration path is to the base path at the decisions runs recorded.

  python -m soe_jax study fidelity RUN_DIR [RUN_DIR ...] [--samples=8] [--alphas=0,1,2] [--out=FILE.json]

Suspect 2 of "why own successes hurt" (README). For each run (a finished run or campaign workdir), its round-0 policy and the episodes its round-1
exploration kept; at every recorded decision (every Ta steps of each kept episode, the observation
history as the policy saw it):
- the base path's own spread: `samples` chunks of D(E(o)) with their executed positions, the mean
  distance of a sample's positions from their mean (mm);
- the exploration path D(q(z)), z ~ N(mu, (alpha sigma)^2) at each alpha (alpha = 0: z = mu), one chunk
  per sample: the distance of its executed positions from the base path's mean (mm);
- the recorded actions' distance from the base path's mean (mm);
- the reconstruction through the bottleneck, q(mu(c)) for c = E(o) of a low-dim policy (the normalised
  history itself), un-normalised: its error in the end effector's position, the object's position and
  their difference (mm; the latest frame).
With the round-0 fit's final beta KL and IB head loss (its record). Distances are over every robot's
executed positions, averaged over the steps of the chunk. Prints a table with a row per run (medians
over its decisions, in mm); `--out` also writes the record (command, commit, machine, per run its
per-decision numbers) for `results/`.
"""

from __future__ import annotations

import dataclasses
import os

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax.analysis import records
from soe_jax.analysis.studies.study import Study, setting
from soe_jax.analysis.tables import markdown
from soe_jax.data.episodes import decisions
from soe_jax.experiment import rundir
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime import atomic, provenance
from soe_jax.runtime.errors import UserError
from soe_jax.train import checkpoint

MM = 1000.0


def _positions(chunks: jax.Array, num_robots: int) -> jax.Array:
  """(..., Ta, A) -> (..., Ta, R, 3)."""
  return chunks.reshape(chunks.shape[:-1] + (num_robots, -1))[..., :3]


def measure(workdir: str, samples: int = 8, alphas=(0.0, 1.0, 2.0), seed: int = 0) -> dict:
  """One run's fidelity (see the module's docstring) -> {method, seed, beta, decisions, per-decision
  arrays in mm, the round-0 fit's final losses}."""
  config = rundir.load_config(workdir)
  run = RunDir(workdir, config)
  if not run.has_checkpoint(0) or not os.path.exists(run.data_path(1)):
    raise UserError(f"{workdir}: needs round 0's policy and round 1's kept episodes ({run.data_path(1)})")
  loaded = checkpoint.load(run.ckpt_dir(0))
  agent, policy, spec = loaded.agent, loaded.policy, loaded.spec
  if not policy.bypass or policy.encoder.__class__.__name__ != "LowDimEncoder":
    raise UserError(f"{workdir}: the fidelity study needs a low-dim policy with the bypass")
  kept = run.kept(atomic.read_json(run.phase_path(1, "explore")))
  robots = len(spec.actions)
  to, ta = policy.n_obs_steps, policy.n_action_steps
  offsets, at = {}, 0
  for k in spec.lowdim_keys:
    offsets[k] = at
    at += int(np.prod(spec.observations[k]["shape"]))

  @jax.jit
  def decide(hist, recorded, key):
    """One decision (To, D), (Ta, A) -> its distances (mm) and reconstruction errors (mm)."""
    batch = jnp.repeat(hist[None], samples, axis=0)
    keys = jax.random.split(key, 1 + len(alphas))
    base = _positions(agent.executed(agent.chunk(batch, keys[0])), robots)  # (S, Ta, R, 3)
    mean = base.mean(0)
    dist = lambda p: jnp.mean(jnp.linalg.norm(p - mean, axis=-1), axis=(-2, -1))  # (...,) mean over steps, robots
    out = dict(base_spread=jnp.mean(dist(base)), recorded=dist(_positions(recorded, robots)))
    for a, k in zip(alphas, keys[1:]):
      chunks, _ = agent.explore_chunk(batch, k, a)
      out[f"explore_alpha{a:g}"] = jnp.mean(dist(_positions(agent.executed(chunks), robots)))
    c = agent.observe(hist[None]).reshape(1, -1)
    mu, _ = policy.latent(agent.params, c)
    back = policy.decode_latent(agent.params, mu).reshape(to, -1)[-1]  # the latest frame, normalised
    raw_back, raw = agent.normalizer.unnormalize_obs(back), hist[-1]
    eef, obj = offsets["robot0_eef_pos"], offsets["object"]
    err = lambda x, y: jnp.linalg.norm(x - y)
    out["recon_eef"] = err(raw_back[eef : eef + 3], raw[eef : eef + 3])
    out["recon_object"] = err(raw_back[obj : obj + 3], raw[obj : obj + 3])
    out["recon_relative"] = err(
      raw_back[eef : eef + 3] - raw_back[obj : obj + 3], raw[eef : eef + 3] - raw[obj : obj + 3]
    )
    return {k: v * MM for k, v in out.items()}

  rows, key = [], jax.random.key(seed)
  for i, ep in enumerate(kept):
    _, hists, recorded = decisions(ep, policy.lowdim_keys, to, ta)
    for j, (h, r) in enumerate(zip(hists, recorded)):
      rows.append(
        jax.device_get(decide(jnp.asarray(h), jnp.asarray(r), jax.random.fold_in(jax.random.fold_in(key, i), j)))
      )
  per = {k: np.round(np.asarray([r[k] for r in rows], float), 3).tolist() for k in rows[0]} if rows else {}
  fit0 = atomic.read_json(run.phase_path(0, "fit"))
  final = fit0.get("final_metrics", {})
  beta = float(config.policy.bypass.beta)
  return dict(
    workdir=workdir,
    method=config.method,
    seed=int(config.seed),
    task=config.env.task,
    beta=beta,
    samples=samples,
    alphas=list(alphas),
    episodes=len(kept),
    decisions=len(rows),
    per_decision=per,
    beta_kl=beta * final["kl"] if "kl" in final else None,
    ib_head_loss=final.get("loss_ib_head"),
  )


@dataclasses.dataclass(frozen=True)
class Fidelity(Study):
  samples: int = setting(8, "Chunks per decision from each path.", lower_bound=2)
  alphas: tuple[float, ...] = setting((0.0, 1.0, 2.0), "The exploration path's scales.")
  name = "fidelity"
  kind = "fidelity"
  usage = "RUN_DIR [RUN_DIR ...]"
  takes = "1+"

  def run(self, paths, config=None):
    """Provenance, then `runs`: each run's `measure`."""
    source = provenance.header()
    return dict(source, runs=[measure(w, self.samples, self.alphas) for w in paths])

  @staticmethod
  def table(committed: records.Records) -> str:
    """A row per run of every record: medians over its decisions (mm), and the round-0 fit's beta KL
    and IB head loss."""
    runs = [run for _, r in committed for run in r["runs"]]
    rows = []
    for r in runs:
      p = r["per_decision"]
      med = lambda k: f"{np.median(p[k]):.1f}" if p.get(k) else "-"
      explore = " / ".join(med(f"explore_alpha{a:g}") for a in r["alphas"])
      kl = "-" if r["beta_kl"] is None else f"{r['beta_kl']:.2e}"
      ib = "-" if r["ib_head_loss"] is None else f"{r['ib_head_loss']:.4f}"
      rows.append([r["task"], r["method"], r["seed"], f"{r['beta']:g}", r["decisions"], med("base_spread"), explore,
                   med("recorded"), med("recon_eef"), med("recon_object"), med("recon_relative"), kl, ib])  # fmt: skip
    header = ["task", "run", "seed", "beta", "decisions", "base spread", "exploration path at alpha "
              + "/".join(f"{a:g}" for a in (runs[0]["alphas"] if runs else [])), "recorded", "q(mu(c)): end effector",
              "object", "end effector - object", "beta KL", "IB head loss"]  # fmt: skip
    return markdown(header, rows) + "\n(medians over the decisions, in mm; distances from the base path's mean)\n"

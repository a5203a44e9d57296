"""A run's explored states with another path's actions, re-fitted and evaluated as a new arm.

  python -m soe_jax study relabel SOURCE_RUN --labels=base|explore|recorded [--alpha=0] [--seed=0]
      [--workdir=<SOURCE_RUN's folder>/<method>] [--results=RESULTS_DIR]

Labels against states (suspect 2 of "why own successes hurt", README): a finished run's round-1
exploration copied into a new run whose kept episodes keep their states but have the actions at every
recorded decision replaced by another path's chunk for the same observation history; the new run then
resumes at round 1's re-fit, paired with the shared control like any arm.

Labels (`labels`):
- `base`: the round-0 policy's base path D(E(o));
- `explore`: its exploration path D(q(z)), z ~ N(mu, (alpha sigma)^2);
- `recorded`: the recorded actions unchanged (the identity: the new run reproduces the source's round).
Chunks are sampled with fold_in(fold_in(key(seed), episode), decision), `seed` the relabelling's own
(a fresh draw of the same path is another seed). The new run's method is `<source>-relabel_<labels>`
(`_alpha<alpha>` for the exploration path, `_s<seed>` for a seed other than 0).

The new run lies beside the source (in its folder, named by its method), shares its round 0, and
resumes at round 1's re-fit as `run` would; running the command again resumes it. `--results` copies
its small files beside a campaign's runs, where it pairs with their control. It writes no record of
its own: the last lines printed are the run's report's path and numbers.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax.analysis import campaign
from soe_jax.analysis import report as run_report
from soe_jax.analysis.studies.study import Study, setting
from soe_jax.data import hdf5
from soe_jax.data.episodes import decisions
from soe_jax.experiment import loop, rundir
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime import atomic, cli, provenance
from soe_jax.runtime.errors import UserError
from soe_jax.train import checkpoint

LABELS = ("base", "explore", "recorded")


def method_name(source: str, labels: str, alpha: float, seed: int) -> str:
  name = f"{source}-relabel_{labels}" + (f"_alpha{alpha:g}" if labels == "explore" else "")
  return name + (f"_s{seed}" if seed else "")


def relabelled(episodes: list[dict], agent, policy, labels: str, alpha: float, seed: int) -> list[dict]:
  """`episodes` with the executed actions at every decision (every Ta steps from 0) replaced by the
  chunk `labels` gives for the observation history the policy saw there."""
  if labels == "recorded":
    return episodes
  to, ta = policy.n_obs_steps, policy.n_action_steps

  @jax.jit
  def chunk(hist, key):
    if labels == "base":
      return agent.executed(agent.chunk(hist, key))
    return agent.executed(agent.explore_chunk(hist, key, alpha)[0])

  out = []
  for i, ep in enumerate(episodes):
    t, hists, _ = decisions(ep, policy.lowdim_keys, to, ta)
    actions = np.array(ep["actions"], np.float32)
    keys = jax.vmap(lambda j: jax.random.fold_in(jax.random.fold_in(jax.random.key(seed), i), j))(jnp.arange(len(t)))
    chunks = np.asarray(jax.vmap(lambda h, k: chunk(h[None], k)[0])(jnp.asarray(hists), keys))
    for d, start in enumerate(t):
      n = min(ta, len(actions) - start)
      actions[start : start + n] = chunks[d, :n]
    out.append(dict(ep, actions=actions))
  return out


def make(source: str, workdir: str, labels: str, alpha: float = 0.0, seed: int = 0) -> str:
  """The relabelled copy of the run `source` in `workdir`, ready to resume at round 1's re-fit -> its
  method name. Refuses an unfinished source exploration or an existing `workdir` of another run."""
  if labels not in LABELS:
    raise UserError(f"unknown labels {labels!r}; known: {', '.join(LABELS)}")
  config = rundir.load_config(source)
  run = RunDir(source, config)
  explore = run.phase_path(1, "explore")
  if not os.path.exists(explore):
    raise UserError(f"{source}: round 1's exploration has not finished ({explore} is missing)")
  config.method = method_name(config.method, labels, alpha, seed)
  config.rounds.round0_dir = os.path.dirname(run.round0)  # the source's shared round 0
  new = RunDir.create(workdir, config)
  if os.path.exists(new.phase_path(1, "explore")):
    return config.method  # made already: resume
  record = atomic.read_json(explore)
  kept = run.kept(record)
  loaded = checkpoint.load(run.ckpt_dir(0))
  episodes = relabelled(kept, loaded.agent, loaded.policy, labels, alpha, seed)
  env_args = hdf5.read_episodes(run.data_path(1))[1] if kept else {}
  os.makedirs(os.path.dirname(new.data_path(1)), exist_ok=True)
  if kept:
    hdf5.write_episodes(
      new.data_path(1), episodes, dict(env_args, relabelled=f"{labels} (alpha {alpha:g}, seed {seed})")
    )
  if os.path.exists(shown := run.shown_path(1, "explore")):
    os.makedirs(new.round_dir(1), exist_ok=True)
    shutil.copyfile(shown, new.shown_path(1, "explore"))
  os.makedirs(new.round_dir(1), exist_ok=True)
  atomic.write_json(new.phase_path(1, "explore"), record)  # last: the exploration counts as done
  return config.method


@dataclasses.dataclass(frozen=True)
class Relabel(Study):
  labels: str = setting(help="Whose chunks label the recorded decisions.", values=LABELS)
  alpha: float = setting(0.0, "The exploration path's scale (labels=explore).", lower_bound=0.0)
  seed: int = setting(0, "The relabelling's sampling seed (another seed: a fresh draw of the same path).")
  workdir: str | None = setting(None, "The new run's directory (default: beside the source, named by its method).")
  results: str | None = setting(
    None, "Also copy the finished run's small files to <results>/<task>/seed<k>/<method>/, as `campaign` does."
  )
  progress: bool = setting(True, "Progress bars.")
  name = "relabel"
  kind = None
  usage = "SOURCE_RUN"
  takes = "1"
  interrupted = cli.PHASES_SAVED

  def run(self, paths, config=None):
    """The relabelled run made, run and reported (and copied to `results`) -> {report: its path,
    summary: its report's numbers}."""
    (source,) = paths
    name = method_name(rundir.load_config(source).method, self.labels, self.alpha, self.seed)
    workdir = self.workdir or os.path.join(os.path.dirname(os.path.abspath(source)), name)
    header = provenance.header()
    make(source, workdir, self.labels, self.alpha, self.seed)
    config = rundir.load_config(workdir)
    loop.run(config, workdir, self.progress)
    summary = run_report.write(workdir)
    if self.results:
      campaign.publish(workdir, config, self.results, dict(header, source_run=os.path.abspath(source)))
    return dict(report=os.path.join(workdir, "report.md"), summary=summary)

  def report(self, record):
    return f"report: {record['report']}\n{json.dumps(record['summary'])}\n"

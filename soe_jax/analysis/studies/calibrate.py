"""How often the verdicts' tests say "different" when nothing is, and their power, on simulated campaigns.

  python -m soe_jax study calibrate RESULTS_DIR --task=lift --nulls=FOLDER[:1+2+3],... [--replicates=20000]
      [--out=results/calibration/<task>.json]

The tests behind the verdicts, on per-state outcomes simulated as the campaigns make them. The per-state
difficulty comes from every evaluation of `--task` in RESULTS_DIR (a campaign's exported runs); tau,
the seed-to-seed spread of a fit, from the null comparisons `--nulls` (each folder's control against
its round 0, or `FOLDER:1+2+3`, each listed round of its control against the one before it). The table
is printed; `--out` writes the record (kind `calibration`).

The design simulated (`simulate`), per replicate and training seed: one round 0, its control and four
exploring arms (dp, sime, soe, soe_steer), each a fit evaluated on the same 200 start states; a state's
difficulty (its logit) is drawn from the records (every evaluation of the folder's task on its states:
(successes + 0.5) / (evaluations + 1), all seeds sharing the states of an `eval.seed`); each fit adds a
random effect on the logit scale, normal with standard deviation tau (0, or tau as the null comparisons
measure it: `null_tau`), and the tested arm (soe) adds an effect worth `effect` points on average.
Success per (fit, state) is a Bernoulli draw. Tested: soe against the control by
- the pooled test (CMH over (seed, state) pairs, i.e. McNemar's over all of them: `metrics.cmh_test`);
- the unmoderated seed-level test (`seed_level.combine`: k - 1 degrees of freedom);
- the moderated seed-level test (`seed_level.moderated` over the family the claims use: round 0, the
  control and the four arms, (k - 1) x 5 degrees of freedom).

tau on the logit scale from tau^2 in points (`null_tau`): two independent fits' difference varies by
2 tau_logit^2 mean(p (1 - p))^2 in points squared, to first order, so tau_logit = sqrt(tau^2 / 2) /
mean(p (1 - p)).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import optimize, special, stats

from soe_jax import metrics
from soe_jax.analysis import aggregate, records, seed_level
from soe_jax.analysis.studies.study import Study, setting
from soe_jax.analysis.tables import markdown
from soe_jax.runtime import provenance
from soe_jax.runtime.errors import UserError

ARMS = ("dp", "sime", "soe", "soe_steer")  # the tested arm is soe
FITS = ("round0", "control") + ARMS
REPLICATES = 20_000
SEEDS = (3, 5)
EFFECTS = (0.0, 0.05, -0.05)


# -- the records -------------------------------------------------------------------------------------
def difficulty(folder: str, task: str) -> np.ndarray:
  """Per start state, the logit of (successes + 0.5) / (evaluations + 1) over every evaluation of
  `task`'s runs in `folder` (all rounds, arms and seeds: they share the states)."""
  tables = [
    np.asarray(v, float)
    for row in aggregate.rows(aggregate.find_runs(folder))
    if row["task"] == task
    for run in row["runs"]
    for v in run["outcomes"]["evaluate"].values()
  ]
  if not tables:
    raise ValueError(f"no evaluations of {task!r} in {folder!r}")
  x = np.stack(tables)
  p = (x.sum(0) + 0.5) / (len(x) + 1)
  return np.log(p / (1 - p))


def null_comparisons(specs: list[str]) -> list[dict]:
  """'FOLDER' (the control's last round against its round 0) or `FOLDER:1+2+3` (each listed round of the
  control against the one before it): a comparison each, over the control's seeds -> [{name, effects,
  z}] with each seed's McNemar z ((gained - lost) / sqrt(gained + lost))."""
  out = []
  for spec in specs:
    folder, _, rounds = spec.partition(":")
    controls = [r for r in aggregate.rows(aggregate.find_runs(folder)) if r["method"] == "control" and not r["variant"]]
    if not controls:
      raise ValueError(f"no control runs in {folder!r}")
    for row in controls:
      runs = row["runs"]
      steps = [(int(r) - 1, int(r)) for r in rounds.split("+")] if rounds else [(0, int(runs[0]["last"]))]
      for a, b in steps:
        pairs = [(run["outcomes"]["evaluate"][str(a)], run["outcomes"]["evaluate"][str(b)]) for run in runs]
        z = []
        for ref, arm in pairs:
          c = metrics.paired_comparison(ref, arm)
          n = c["gained"] + c["lost"]
          z.append((c["gained"] - c["lost"]) / math.sqrt(n) if n else 0.0)
        out.append(dict(name=f"{folder} ({row['task']}) round {b} against {a}", effects=seed_level.effects(pairs), z=z))
  return out


def null_tau(nulls: list[dict], logits: np.ndarray) -> dict:
  """The between-seed variance of the null comparisons (Paule-Mandel, pooled over them), in points and
  on the logit scale for states of difficulty `logits`; beside it, the variance of the per-seed McNemar z."""
  family = [n["effects"] for n in nulls if len(n["effects"].d) > 1]
  tau2 = seed_level.tau2_pm(family)
  p = special.expit(logits)
  z = np.concatenate([n["z"] for n in nulls])
  return dict(
    tau2_points=tau2,
    tau_points=math.sqrt(tau2),
    tau_logit=math.sqrt(tau2 / 2) / float(np.mean(p * (1 - p))),
    z_variance=float(np.var(z, ddof=1)),
    comparisons=[n["name"] for n in nulls],
    seeds=int(sum(len(n["effects"].d) for n in nulls)),
  )


def logit_shift(logits: np.ndarray, points: float) -> float:
  """The shift on the logit scale that moves the mean success over these states by `points`."""
  if points == 0:
    return 0.0
  base = float(special.expit(logits).mean())
  return float(optimize.brentq(lambda s: special.expit(logits + s).mean() - base - points, -20, 20))


# -- the tests, batched over replicates ---------------------------------------------------------------
def _residuals(d: np.ndarray, v: np.ndarray, tau2: np.ndarray) -> np.ndarray:
  """(R, C, K) differences and variances, (R,) tau^2 -> (R,) sum of w (d - mu_c)^2."""
  w = 1.0 / (v + tau2[:, None, None])
  mu = (w * d).sum(-1, keepdims=True) / w.sum(-1, keepdims=True)
  return (w * (d - mu) ** 2).sum((-2, -1))


def tau2_pm(d: np.ndarray, v: np.ndarray, iterations: int = 64) -> np.ndarray:
  """`seed_level.tau2_pm` for R families at once, (R, C, K) -> (R,), by bisection on [0, 1] (a
  difference of rates is at most 1 in size)."""
  df = d.shape[1] * (d.shape[2] - 1)
  lo, hi = np.zeros(len(d)), np.ones(len(d))
  for _ in range(iterations):
    mid = (lo + hi) / 2
    above = _residuals(d, v, mid) > df
    lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
  return np.where(_residuals(d, v, np.zeros(len(d))) <= df, 0.0, (lo + hi) / 2)


def unmoderated(d: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
  """`seed_level.combine` for R comparisons at once: (R, K) differences and variances -> (estimate, p)."""
  dd, vv = d[:, None], v[:, None]
  tau2 = tau2_pm(dd, vv)
  df = d.shape[1] - 1
  scale = _residuals(dd, vv, tau2) / df
  w = 1.0 / (v + tau2[:, None])
  mu = (w * d).sum(-1) / w.sum(-1)
  se = np.sqrt(np.maximum(1.0, scale) / w.sum(-1))
  return mu, 2 * stats.t.sf(np.abs(mu) / se, df)


def moderated(y: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
  """`seed_level.moderated` for R families at once: (R, K, F) per-seed summaries, fit a against fit b
  -> (estimate, p)."""
  mse, df = seed_level.residual_variance(y)
  mu = (y[:, :, a] - y[:, :, b]).mean(-1)
  return mu, 2 * stats.t.sf(np.abs(mu) / np.sqrt(2 * mse / y.shape[1]), df)


def _paired(ref: np.ndarray, arm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
  """(..., N) outcomes -> d, v (`seed_level.paired`), gained, lost."""
  n = ref.shape[-1]
  g, lost = (arm & ~ref).sum(-1), (ref & ~arm).sum(-1)
  d = (g - lost) / n
  return d, np.maximum(((g + lost) / n - d * d) / n, 1.0 / n**2), g, lost


def simulate(logits: np.ndarray, tau_logit: float, seeds: int, effect: float, replicates: int = REPLICATES,
             seed: int = 0, chunk: int = 2_000) -> dict:  # fmt: skip
  """Each test's rate of p < 0.05 (for a non-zero `effect`, in its direction) over `replicates`
  simulated campaigns (`FITS` per seed, `seeds` seeds)."""
  rng = np.random.default_rng(seed)
  shift = logit_shift(logits, effect)
  arm_shift = np.array([shift if f == "soe" else 0.0 for f in FITS])
  hits = dict(pooled=0, unmoderated=0, moderated=0)
  done = 0
  while done < replicates:
    r = min(chunk, replicates - done)
    fit = rng.normal(0.0, tau_logit, (r, seeds, len(FITS), 1)) + arm_shift[:, None]
    success = rng.random((r, seeds, len(FITS), len(logits))) < special.expit(logits + fit)
    control, soe = success[:, :, FITS.index("control")], success[:, :, FITS.index("soe")]
    d, v, g, lost = _paired(control, soe)
    g, lost = g.sum(-1), lost.sum(-1)
    stat = np.where(g + lost > 0, (g - lost) ** 2 / np.maximum(g + lost, 1), 0.0)
    results = dict(
      pooled=(g - lost, special.erfc(np.sqrt(stat / 2))),
      unmoderated=unmoderated(d, v),
      moderated=moderated(success.mean(-1), FITS.index("soe"), FITS.index("control")),
    )
    for name, (estimate, p) in results.items():
      right = np.ones(r, bool) if effect == 0 else np.sign(estimate) == np.sign(effect)
      hits[name] += int(((p < 0.05) & right).sum())
    done += r
  return {k: h / replicates for k, h in hits.items()}


def calibration(folder: str, task: str, null_specs: list[str], replicates: int = REPLICATES, seed: int = 0) -> dict:
  """The calibration of `task`'s tests: the null comparisons' tau, then each cell (tau 0 or measured,
  3 or 5 seeds, effect 0 or +-5 points) -> the record's body."""
  logits = difficulty(folder, task)
  tau = null_tau(null_comparisons(null_specs), logits)
  cells = []
  for tau_name, tau_logit in (("0", 0.0), ("measured", tau["tau_logit"])):
    for k in SEEDS:
      for effect in EFFECTS:
        rates = simulate(logits, tau_logit, k, effect, replicates, seed)
        cells.append(dict(tau=tau_name, tau_logit=tau_logit, seeds=k, effect=effect, rates=rates))
  p = special.expit(logits)
  return dict(task=task, folder=folder, states=len(logits), mean_success=float(p.mean()), null=tau,
              replicates=replicates, cells=cells)  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Calibrate(Study):
  task: str = setting(help="The task whose start states' difficulty the simulation draws.")
  nulls: tuple[str, ...] = setting(help="The null comparisons that measure tau: FOLDER or FOLDER:ROUND+ROUND+...")
  replicates: int = setting(REPLICATES, "Simulated campaigns per cell.", lower_bound=100)
  seed: int = setting(0, "The simulation's random seed.")
  name = "calibrate"
  kind = "calibration"
  usage = "RESULTS_DIR"
  takes = "1"
  compiles = False

  def run(self, paths, config=None):
    """Provenance, then the `calibration` of `task` on the folder `paths[0]`."""
    (folder,) = paths
    source = provenance.header()
    try:
      return dict(source, **calibration(folder, self.task, list(self.nulls), self.replicates, self.seed))
    except ValueError as e:
      raise UserError(str(e)) from None

  @staticmethod
  def table(committed: records.Records) -> str:
    """Per task, tau and seeds: each test's false-positive rate (effect 0) and power (+-5 points) at 0.05."""
    rows = []
    for _, r in committed:
      for c in r["cells"]:
        kind = "false positives" if c["effect"] == 0 else f"power at {100 * c['effect']:+.0f} points"
        tau = "0" if c["tau"] == "0" else f"{c['tau_logit']:.2f} (measured: {100 * r['null']['tau_points']:.1f} points)"
        rates = c["rates"]
        rows.append([r["task"], tau, c["seeds"], kind, f"{rates['pooled']:.3f}", f"{rates['unmoderated']:.3f}",
                     f"{rates['moderated']:.3f}", f"{r['replicates']:,}"])  # fmt: skip
    header = ["task", "tau (logit)", "seeds", "rate of p < 0.05", "pooled CMH", "seed-level (k - 1 df)",
              "seed-level, moderated (verdicts)", "replicates"]  # fmt: skip
    return markdown(header, rows)

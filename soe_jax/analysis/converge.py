"""Is a round-0 fit converged? Success along the fit, and what more training on the same data does.

  python -m soe_jax converge --config=configs/lift.py:cpu [--eval_every=1000] [--eval_states=50]
      [--check_states=400] [--extra=0.5] [--workdir=DIR] [--out=results/<study>/<name>.json]

1. Round 0 as `run` runs it (demonstrations, fit, evaluation; shared with runs of the same settings),
   its EMA policy evaluated every `eval_every` steps on `eval_states` start states.
2. The same fit continued for `extra` x its steps on the same data: round 1's re-fit without new data,
   as the loop's continued re-fit runs it (`rounds.refit_lr`, round 1's keys), i.e. the control a
   self-improvement round is measured against. Its in-fit evaluations use the same states and key.
3. Both policies evaluated on `check_states` start states of the evaluation seed with one sampling key
   (paired), and `metrics.convergence`: converged if the continuation changes success by less than 3
   points and the last two in-fit evaluations of round 0 are within 5 points.

Each step is a saved phase of the workdir (default `runs/converge/<task>-<round-0 hash>`), so an
interrupted benchmark resumes. `--out` writes the record for `results/`: the command, commit,
machine, config, the phase records and the check."""

from __future__ import annotations

import json
import os

import ml_collections

from soe_jax import metrics
from soe_jax.analysis import record
from soe_jax.data.episodes import EpisodeSet
from soe_jax.experiment import loop, rundir, validation
from soe_jax.runtime import atomic, provenance
from soe_jax.runtime.errors import UserError

_CHECK = 5  # key stream of the paired check


def settings(config, eval_every: int, eval_states: int) -> ml_collections.ConfigDict:
  """`config` (unlocked copy) with in-fit evaluations on; its rounds do not matter here."""
  config = ml_collections.ConfigDict(json.loads(config.to_json()))
  config.fit.update(eval_every=int(eval_every), eval_states=int(eval_states))
  return config


def run(
  config: ml_collections.ConfigDict,
  workdir: str | None = None,
  eval_every: int = 1000,
  eval_states: int = 50,
  check_states: int = 400,
  extra: float = 0.5,
  progress: bool = True,
) -> dict:
  """-> {command, commit, machine, round0_dir, config, fit: round 0's fit record (with its in-fit
  evaluations), continued: the continuation's, check: metrics.convergence with both evaluations}."""
  source = provenance.header()  # the code as it was when the measurement started
  config = settings(config, eval_every, eval_states)
  if eval_every < 1 or check_states < 1 or not 0 < extra:
    raise UserError(f"need eval_every >= 1, check_states >= 1, extra > 0; got {eval_every}, {check_states}, {extra}")
  validation.check(config)
  workdir = workdir or os.path.join("runs", "converge", rundir.round0_key(config))
  with loop.opened(config, workdir, progress) as exp:
    demos, norm, state = loop.round0(exp)
    fit0 = atomic.read_json(exp.dir.phase_path(0, "fit"))
    if "eval_curve" not in fit0:
      raise UserError(
        f"the round 0 in {exp.dir.round0} was fitted without in-fit evaluations; give this benchmark a "
        "round 0 of its own with --config.rounds.round0_dir=DIR"
      )
    steps = max(1, round(extra * int(config.fit.num_steps)))
    more = exp.fit_phase(1, [EpisodeSet(demos, 0)], norm, state, steps)
    fit1 = atomic.read_json(exp.dir.phase_path(1, "fit"))

    def check():
      key = exp.key(0, _CHECK)
      before = exp.evaluate(state, 0, check_states, key)
      after = exp.evaluate(more, 1, check_states, key)
      rates = [p["success_rate"] for p in fit0["eval_curve"]]
      return dict(before=before, after=after, **metrics.convergence(before["success"], after["success"], rates)), None

    return record.record(source, exp, fit=fit0, continued=fit1, check=exp.phase(1, "check", check)[0])


def curve_lines(result: dict) -> list[str]:
  """The curve and the check, as printed."""
  fit, check = result["fit"], result["check"]
  lines = ["step | success | fit time | with evaluations"]
  for name, phase in (("round 0", fit), ("continued", result["continued"])):
    offset = 0 if name == "round 0" else fit["steps"]
    base = (0.0, 0.0) if name == "round 0" else (fit["time_steps_s"], fit["eval_curve"][-1]["wall_s"])
    for p in phase["eval_curve"]:
      lines.append(
        f"{offset + p['step']:>6} | {100 * p['success_rate']:5.1f}% | {base[0] + p['fit_s']:7.0f} s "
        f"| {base[1] + p['wall_s']:7.0f} s   ({name})"
      )
  b, a = check["before"], check["after"]
  lines.append(
    f"check on {b['num_rollouts']} paired states: {100 * b['success_rate']:.1f}% -> {100 * a['success_rate']:.1f}% "
    f"({100 * check['difference']:+.1f} points [{100 * check['low']:+.1f}, {100 * check['high']:+.1f}], "
    f"{check['gained']} gained / {check['lost']} lost, McNemar p={check['p_value']:.3f}); last two in-fit "
    f"evaluations {100 * (check['last_two_change'] or 0):.0f} points apart: "
    + ("converged" if check["converged"] else "NOT converged")
  )
  return lines

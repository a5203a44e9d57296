"""Is round 0 converged? A fit, its in-fit evaluations and a paired continuation.

  python -m soe_jax study converge --config=configs/lift.py:cpu [--eval_every=1000] [--eval_states=50]
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
interrupted study resumes. Prints the success along the fit and the check, then the check as one JSON
object; `--out` also writes the record for `results/`: the command, commit, machine, config, the
phase records and the check."""

from __future__ import annotations

import dataclasses
import json
import os

import ml_collections

from soe_jax import metrics
from soe_jax.analysis import records
from soe_jax.analysis.studies.study import Study, setting
from soe_jax.analysis.tables import markdown, pct
from soe_jax.data.episodes import EpisodeSet
from soe_jax.experiment import loop, rundir, validation
from soe_jax.runtime import atomic, cli, provenance
from soe_jax.runtime.errors import UserError

_CHECK = 5  # key stream of the paired check


def settings(config, eval_every: int, eval_states: int) -> ml_collections.ConfigDict:
  """`config` (unlocked copy) with in-fit evaluations on; its rounds do not matter here."""
  config = ml_collections.ConfigDict(json.loads(config.to_json()))
  config.fit.update(eval_every=int(eval_every), eval_states=int(eval_states))
  return config


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


def _against_first(r: dict, first: dict) -> str:
  """A converge record's fit against the first record's on the same check states (same task, evaluation
  seed and count; the sampling keys follow the training seed): difference, gained / lost, p."""
  same = lambda rec: (rec["config"].get("env", {}).get("task"), rec["config"].get("eval", {}).get("seed"),
                      rec["config"].get("seed"))  # fmt: skip
  a, b = first["check"]["before"], r["check"]["before"]
  if r is first or same(r) != same(first) or a["num_rollouts"] != b["num_rollouts"] or "success" not in a:
    return "-"
  c = metrics.paired_comparison(a["success"], b["success"])
  return f"{100 * c['difference']:+.1f} pts, {c['gained']} / {c['lost']} (p={c['p_value']:.2g})"


@dataclasses.dataclass(frozen=True)
class Converge(Study):
  eval_every: int = setting(1000, "Fit steps between in-fit evaluations.")
  eval_states: int = setting(50, "Start states of each in-fit evaluation.")
  check_states: int = setting(400, "Paired start states of the convergence check.")
  extra: float = setting(0.5, "The continuation's steps, as a fraction of the fit's.")
  workdir: str | None = setting(None, "Its run directory (default runs/converge/<round-0 key>).")
  progress: bool = setting(True, "Progress bars.")
  name = "converge"
  kind = "converge"
  config = True
  interrupted = cli.PHASES_SAVED

  def run(self, paths, config):
    """-> {command, commit, machine, round0_dir, config, fit: round 0's fit record (with its in-fit
    evaluations), continued: the continuation's, check: metrics.convergence with both evaluations}."""
    source = provenance.header()  # the code as it was when the measurement started
    config = settings(config, self.eval_every, self.eval_states)
    if self.eval_every < 1 or self.check_states < 1 or not 0 < self.extra:
      got = f"{self.eval_every}, {self.check_states}, {self.extra}"
      raise UserError(f"need eval_every >= 1, check_states >= 1, extra > 0; got {got}")
    validation.check(config)
    workdir = self.workdir or os.path.join("runs", "converge", rundir.round0_key(config))
    with loop.opened(config, workdir, self.progress) as exp:
      demos, norm, state = loop.round0(exp)
      fit0 = atomic.read_json(exp.dir.phase_path(0, "fit"))
      if "eval_curve" not in fit0:
        raise UserError(
          f"the round 0 in {exp.dir.round0} was fitted without in-fit evaluations; give this study a "
          "round 0 of its own with --config.rounds.round0_dir=DIR"
        )
      steps = max(1, round(self.extra * int(config.fit.num_steps)))
      more = exp.fit_phase(1, [EpisodeSet(demos, 0)], norm, state, steps)
      fit1 = atomic.read_json(exp.dir.phase_path(1, "fit"))

      def check():
        key = exp.key(0, _CHECK)
        before = exp.evaluate(state, 0, self.check_states, key)
        after = exp.evaluate(more, 1, self.check_states, key)
        rates = [p["success_rate"] for p in fit0["eval_curve"]]
        return dict(before=before, after=after, **metrics.convergence(before["success"], after["success"], rates)), None

      return records.record(source, exp, fit=fit0, continued=fit1, check=exp.phase(1, "check", check)[0])

  @staticmethod
  def table(committed: records.Records) -> str:
    """`converge` records: the setting (fields differing from the first record's config), the fit,
    success along it, the paired check of continuing it, and the fit against the first record's on the
    same check states."""
    first = committed[0][1]["config"]
    rows = []
    for name, r in committed:
      fit, check = r["fit"], r["check"]
      curve = " / ".join(f"{100 * p['success_rate']:.0f}" for p in fit["eval_curve"])
      b, a = check["before"], check["after"]
      rows.append([
        name,
        records.differing_settings(r["config"], first),
        r["commit"],
        f"{fit['steps']:,}",
        f"{fit['time_steps_s']:.0f} s ({fit['time_total_s']:.0f} s)",
        curve,
        f"{pct(b['success_rate'])} -> {pct(a['success_rate'])} (n={b['num_rollouts']})",
        f"{100 * check['difference']:+.1f} [{100 * check['low']:+.1f}, {100 * check['high']:+.1f}] pts, "
        f"p={check['p_value']:.3f}",
        "yes" if check["converged"] else "no",
        _against_first(r, committed[0][1]),
      ])  # fmt: skip
    header = ["record", "setting", "commit", "steps", "fit time (with in-fit evaluations)", "in-fit success (50 states)",
              "check: fit -> continued (paired states)", "difference [95% CI], p", "converged",
              "fit against the first record's (paired)"]  # fmt: skip
    return markdown(header, rows)

  def report(self, record):
    """The curve and the check, then the check as one JSON object."""
    check = record["check"]
    summary = {k: check[k] for k in ("converged", "difference", "low", "high", "p_value")}
    return "\n".join(curve_lines(record) + [json.dumps(summary)]) + "\n"

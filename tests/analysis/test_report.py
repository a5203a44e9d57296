"""What a run's report says where a number alone would mislead: a relative improvement over a round 0 of
0% is undefined, one round's wall time is labelled, and the exploration figure says what it counts."""

from soe_jax.analysis import report


def _summary(**kw):
  s = dict(task="lift", method="soe", seed=0, rounds=[0, 1], k=5, pass_at_k_per_round=[None, 0.4])
  s.update(rollouts_per_round=[None, 70], **kw)
  return s


def test_a_relative_improvement_over_0_percent_is_undefined():
  assert report._improvement(_summary(improvement_abs=0.0, improvement_rel=None)) == "undefined: 0% before (+0.0 pts)"
  assert report._improvement(_summary(improvement_abs=0.05, improvement_rel=0.1)) == "+10.0% (+5.0 pts)"


def test_one_rounds_wall_time_is_labelled():
  (line, _) = report._round_wall_lines(_summary(round_wall_s=412.4))
  assert line.startswith("One round's wall time (explore, re-fit, evaluate; round 1): 412 s"), line
  (line, _) = report._round_wall_lines(_summary(rounds=[0, 1, 2, 3], round_wall_s=400.0))
  assert "the mean over rounds 1 to 3" in line and "`round_wall_s`" in line, line
  assert report._round_wall_lines(_summary(rounds=[0])) == []


def test_the_exploration_figure_says_what_rollouts_count():
  fig = report.exploration_figure(_summary())
  labels = [t.get_text() for ax in fig.axes for legend in [ax.get_legend()] if legend for t in legend.get_texts()]
  assert any("tries up to its first success (5 without one), summed over start states" in t for t in labels), labels
  assert report.exploration_figure(_summary(pass_at_k_per_round=[None, None])) is None

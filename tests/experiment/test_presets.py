"""The presets every config file shares (`presets`), the tasks' own numbers under them, and overrides of
a config file's fields."""

import ml_collections
import pytest

from configs import can as can_config
from configs import lift as lift_config
from configs import square as square_config
from soe_jax.experiment import rundir, validation
from soe_jax.runtime import configfile


def test_method_presets_choose_the_strategy():
  for method in ("dp", "sime", "soe", "soe_steer"):
    config = lift_config.get_config(f"cpu,{method}")
    assert config.method == config.explore.strategy.name == method
  assert lift_config.get_config("cpu,soe_steer").explore.strategy.kwargs.every == 4
  assert lift_config.get_config("smoke,soe").explore.strategy.kwargs.to_dict() == {"alpha": 2.0, "hold": 1}
  with pytest.raises(ValueError, match="choose one method preset"):
    lift_config.get_config("soe,dp")
  with pytest.raises(
    ValueError,
    match="known presets: smoke, cpu, head, image, expert_data, protocol, select, length_cap, alpha, hold, beta, demo_fraction, aligned, range, frame, style, refit, dp,",
  ):
    lift_config.get_config("fast")
  with pytest.raises(ValueError, match="expert_data goes with an exploring method"):
    lift_config.get_config("control,expert_data")


def test_variant_presets_set_and_name_their_field():
  """A variant sets its field and adds itself to the method's name."""
  c = lift_config.get_config("cpu,soe,select=shortest_success,length_cap=1.5,hold=4,alpha=1")
  assert c.method == "soe-select_shortest_success-cap1.5-alpha1-hold4"
  assert (c.rounds.select, c.rounds.length_cap) == ("shortest_success", 1.5)
  assert c.explore.strategy.kwargs.to_dict() == {"alpha": 1.0, "hold": 4}
  assert lift_config.get_config("sime,select=sime,expert_data").method == "sime-expert_data-select_sime"
  ablated = lift_config.get_config("soe,beta=0")
  assert (ablated.method, ablated.policy.bypass.beta) == ("soe-beta0", 0.0)
  assert rundir.round0_key(ablated) != rundir.round0_key(lift_config.get_config("soe"))  # a round 0 of its own
  mixed = lift_config.get_config("dp,demo_fraction=0.5,aligned=true")  # the re-fit's sampling: an arm's settings
  assert (mixed.method, mixed.rounds.demo_fraction, mixed.rounds.aligned_windows) == ("dp-demos0.5-aligned", 0.5, True)
  assert lift_config.get_config("dp,aligned=false").method == "dp"  # the default's value: no other arm
  assert rundir.round0_key(mixed) == rundir.round0_key(lift_config.get_config("dp"))  # round 0 shared
  old = lift_config.get_config("control,range=demonstrations")  # any method, the control too
  assert (old.method, old.policy.action_range, lift_config.get_config("").policy.action_range) == (
    "control-range_demonstrations",
    "demonstrations",
    "workspace",
  )
  rel = lift_config.get_config("control,range=demonstrations,frame=chunk_relative")  # relative actions: an arm
  assert (rel.method, rel.policy.action_frame) == (
    "control-range_demonstrations-frame_chunk_relative",
    "chunk_relative",
  )
  assert rundir.round0_key(rel) != rundir.round0_key(old)  # with a round 0 of its own
  # A config saved before the field (read as `demonstrations`) keeps its round 0; the default has its own.
  saved = rundir.plain(old)
  del saved["policy"]["action_range"]
  assert rundir.round0_key(ml_collections.ConfigDict(rundir.with_added(saved))) == rundir.round0_key(old)
  assert rundir.round0_key(old) != rundir.round0_key(lift_config.get_config("control"))
  for presets, message in [
    ("control,select=sime", "goes with an exploring method"),
    ("soe,alpha", "needs a value: alpha=VALUE"),
    ("dp,hold=2", "strategy 'dp' has no setting 'hold'"),
    ("soe,hold=two", "hold=two: expected a int, e.g. hold=1"),
    ("soe,aligned=1", "aligned=1: expected true or false"),
  ]:
    with pytest.raises(ValueError, match=message):
      lift_config.get_config(presets)


def test_cpu_preset_takes_each_tasks_demos_and_steps():
  """Under `cpu` each task has its own number of demonstrations and round-0 steps."""
  lift, can, square = (config.get_config("cpu") for config in (lift_config, can_config, square_config))
  assert (lift.data.num_demos, lift_config.get_config("").data.num_demos) == (5, 10)
  assert can.data.num_demos == square.data.num_demos == can_config.get_config("").data.num_demos == 20
  assert [c.fit.num_steps for c in (lift, can, square)] == [12_500, 20_000, 20_000]
  assert lift.policy.head.kwargs.down_dims == (32, 64, 128) and lift.fit.lr == 1e-3 and lift.rounds.refit_lr == 3e-4
  assert can_config.get_config("cpu,smoke").data.num_demos == 4  # smoke stays tiny
  image = lift_config.get_config("cpu,image")  # Lift's image recipe: robomimic's 10, the narrow trunk, 7.5k steps
  assert (image.data.num_demos, image.fit.num_steps, can_config.get_config("cpu,image").fit.num_steps) == (
    10,
    7_500,
    4_000,
  )
  assert image.policy.encoder.kwargs.widths == (8, 16, 32, 64) and image.env.image_size == 84


def test_cpu_preset_adopts_the_kl_weight_and_aligned_windows_and_its_variants_still_set_them():
  """Under `cpu` the bypass's KL weight is 1e-5 and self-collected episodes' re-fit windows start at
  decisions (RESULTS.md, "why own successes hurt"), for every arm but the oracles; `beta=`/`aligned=`
  set them back, and an arm is named by what its variants change."""
  for task in (lift_config, can_config, square_config):
    for method in ("control", "dp", "sime", "soe", "soe_steer"):
      c = task.get_config(f"cpu,{method}")
      assert (c.method, c.policy.bypass.beta, c.rounds.aligned_windows) == (method, 1e-5, True)
  assert lift_config.get_config("cpu,dp,expert_data").rounds.aligned_windows is False  # scripted episodes
  assert (lift_config.get_config("").policy.bypass.beta, lift_config.get_config("").rounds.aligned_windows) == (
    1e-3,
    False,
  )
  old = lift_config.get_config("cpu,soe,beta=0.001,aligned=false")
  assert (old.method, old.policy.bypass.beta, old.rounds.aligned_windows) == (
    "soe-beta0.001-aligned_false",
    1e-3,
    False,
  )
  assert rundir.round0_key(old) != rundir.round0_key(lift_config.get_config("cpu,soe"))  # its own round 0
  assert lift_config.get_config("cpu,soe,beta=1e-05,aligned=true").method == "soe"  # changes nothing


def test_a_protocol_names_the_arm_only_where_it_changes_the_presets_fields():
  """`cpu` runs SIME's protocol, so `protocol=sime` changes nothing there; `protocol=continued`, the first
  campaigns' protocol, changes every one of its fields and names the arm and its own round 0."""
  plain, sime = lift_config.get_config("cpu,soe"), lift_config.get_config("cpu,soe,protocol=sime")
  assert sime.method == "soe" and sime.to_dict() == plain.to_dict()
  continued = lift_config.get_config("cpu,soe,protocol=continued")
  assert continued.method == "soe-protocol_continued" and rundir.round0_key(continued) != rundir.round0_key(plain)
  fields = lambda c: (c.policy.n_obs_steps, c.policy.horizon, c.policy.n_action_steps, c.rounds.select, c.rounds.refit)
  assert (fields(plain), fields(continued)) == ((1, 20, 20, "sime", "scratch"), (2, 16, 8, "first_success", "continue"))
  with pytest.raises(ValueError, match="unknown protocol 'paper'; known protocols: sime, continued"):
    lift_config.get_config("cpu,soe,protocol=paper")


def test_the_refit_variant_names_any_arm_and_shares_round_0():
  """`refit=continue` under `cpu` (SIME's from-scratch re-fit) names the arm, the control's too, and keeps
  round 0; a value the loop does not know is refused by the config's check."""
  for method in ("control", "soe"):
    plain, continued = lift_config.get_config(f"cpu,{method}"), lift_config.get_config(f"cpu,{method},refit=continue")
    assert (continued.method, continued.rounds.refit, plain.rounds.refit) == (
      f"{method}-refit_continue",
      "continue",
      "scratch",
    )
    assert rundir.round0_key(continued) == rundir.round0_key(plain)
  assert lift_config.get_config("cpu,soe,refit=scratch").method == "soe"  # the preset's own: no other arm
  both = lift_config.get_config("cpu,soe,refit=continue,protocol=continued")  # each names what it changed
  assert both.method == "soe-refit_continue-protocol_continued"
  with pytest.raises(ValueError, match="unknown re-fit mode 'warm'; known: continue, scratch"):
    validation.check(lift_config.get_config("cpu,soe,refit=warm"))


def test_the_cpu_preset_is_the_protocol_the_rule_picked():
  """docs/protocol.md applied (RESULTS.md, "Applying the rule"), for every arm: the workspace box, SIME's
  protocol (one observation step, 20-step chunks executed whole, `train_0.5` selection, re-fits from
  fresh parameters), varied demonstrations at each task's calibrated count, the KL weight 1e-5,
  aligned windows (not for the oracles' scripted episodes), and the paper's exploration settings."""
  from soe_jax.experiment import presets

  for config, demos in ((lift_config, 5), (can_config, 20), (square_config, 20)):
    for method in ("control", "dp", "sime", "soe", "soe_steer", "dp,expert_data"):
      c = config.get_config(f"cpu,{method}")
      p = c.policy
      assert (p.action_range, p.n_obs_steps, p.horizon, p.n_action_steps) == ("workspace", 1, 20, 20)
      assert (c.rounds.select, c.rounds.refit, c.rounds.num_rounds) == ("sime", "scratch", 1)
      assert (c.data.demo_style, c.data.num_demos, p.bypass.beta) == ("varied", demos, 1e-5)
      assert c.rounds.aligned_windows == (c.rounds.new_data != "expert")
      name = c.explore.strategy.name
      if name != "soe_steer":  # (steering is lighter under `cpu`; its sampling is soe's)
        assert c.explore.strategy.kwargs.to_dict() == presets.strategy_config(name).kwargs.to_dict()


def test_a_misspelled_override_suggests_the_field():
  argv = [
    "--config.fit.stepz=3",
    "--config.rounds.num_round=2",
    "--config.fit.lr=1e-3",
    "--config.policy.head.kwargs=x",
  ]
  assert configfile.unknown_overrides("configs/lift.py:smoke", argv) == [
    "fit.stepz (did you mean fit.num_steps?)",
    "rounds.num_round (did you mean rounds.num_rounds?)",
  ]


def test_smoke_keeps_the_task_horizon_for_varied_demonstrations():
  """`cpu,smoke` draws varied demonstrations, whose slower styles need 40-80 of Lift's steps: smoke's
  24-step episodes left the demonstrator short of its successes (the run stopped with a traceback)."""
  assert configfile.load("configs/lift.py:smoke").env.episode_length == 24
  assert configfile.load("configs/lift.py:cpu,smoke").env.episode_length == 400

"""The scripted demonstrators run batched under jit and solve the task; variety and determinism; and
`python -m soe_jax experts`."""

import json

import jax
import numpy as np
import pytest

from soe_jax.commands import experts as experts_command
from soe_jax.data import hdf5
from soe_jax.experts import collect, transport, variety
from soe_jax.experts.registry import EXPERTS, make_expert

# Lift's 24 start states for the scripted and the varied demonstrator (one compiled program each).
LIFT_KEYS = jax.random.split(jax.random.PRNGKey(3), 24)


@pytest.fixture(scope="module")
def scripted_lift(jitted_env):
  """The scripted demonstrator's batch on Lift's 24 start states: (env, batch)."""
  env, _, _ = jitted_env("lift")
  return env, collect.run_demos(env, make_expert("lift"), LIFT_KEYS, progress=False)


def test_lift_demonstrations_succeed_and_vary(scripted_lift):
  env, batch = scripted_lift
  keys = LIFT_KEYS
  assert batch["success"].all()
  assert batch["length"].std() > 0  # randomised timing
  episodes = collect.split_episodes(batch)
  assert [e["actions"].shape[0] for e in episodes] == list(batch["length"])
  # Smooth: commanded positions move less than 3 cm per step.
  for e in episodes:
    assert np.abs(np.diff(e["actions"][:, :3], axis=0)).max() < 0.03
  # robomimic's fields: states [time, qpos, qvel] in float64, and each step's next observation.
  e, nq, nv = episodes[0], env.mj_model.nq, env.mj_model.nv
  assert e["states"].dtype == np.float64 and e["states"].shape == (len(e["actions"]), 1 + nq + nv)
  assert e["states"][0, 0] == 0.0 and np.all(np.diff(e["states"][:, 0]) > 0)  # time from the reset on
  for k in e["obs"]:
    np.testing.assert_array_equal(e["next_obs"][k][:-1], e["obs"][k][1:])
  again = collect.run_demos(env, make_expert("lift"), keys, progress=False)
  np.testing.assert_array_equal(batch["actions"], again["actions"])


def test_the_varied_lift_demonstrator_arcs_both_ways_grasps_both_faces_and_hovers(scripted_lift):
  """`style=varied`: on 24 start states every episode succeeds, and the measured styles (read from the
  commanded actions alone) show arcs to each side, both face pairs and hovers, none of which the
  scripted demonstrator's episodes from the same states show (its faces follow the cube's yaw)."""
  env, batch = scripted_lift
  varied = variety.measure(collect.run_demos(env, make_expert("lift", "varied"), LIFT_KEYS, progress=False))
  scripted = variety.measure(batch)
  assert varied["success_rate"] == 1.0
  assert min(varied["arc_left"], varied["arc_right"], varied["face_0"], varied["face_1"], varied["paused"]) > 0.1
  assert scripted["straight"] == 1.0 and scripted["paused"] == 0.0
  assert varied["length_std"] > scripted["length_std"]


def _carried(turn: float, face_yaw: float, n: int = 40) -> tuple[np.ndarray, np.ndarray]:
  """A synthetic pick-and-place read by the measure: the hand goes straight 10 cm, closes at step 10
  with its closing axis at `face_yaw` to the object, carries it while the object turns by `turn` (rad)
  and releases at step 30."""
  actions = np.zeros((n, 10))
  actions[:, 0] = np.minimum(np.arange(n), 10) * 0.01
  actions[:, 3:5] = [np.cos(face_yaw), np.sin(face_yaw)]
  actions[:, 9] = np.where((np.arange(n) >= 10) & (np.arange(n) < 30), 1.0, -1.0)
  yaw = np.clip(np.arange(n) - 10, 0, 20) / 20 * turn
  pose = np.zeros((n, 7))
  pose[:, 5], pose[:, 6] = np.sin(yaw / 2), np.cos(yaw / 2)  # xyzw about z
  return actions, pose


def test_the_measure_reads_faces_and_turns_from_the_commands():
  """The face is the closing axis against the object's yaw (quarter turns apart); the turn is how far
  the object turned between grasp and release: under an eighth of a turn the short way, else the
  long way to the next square orientation (Square's equivalents: its handle is the one grasp)."""
  short, long = variety.episode(*_carried(0.3, 0.0)), variety.episode(*_carried(-1.2, np.pi / 2))
  assert (short["turn"], short["face"], short["side"]) == (0, 0, 0) and (long["turn"], long["face"]) == (1, 1)
  n = 4
  batch = dict(success=np.ones(n, bool), length=np.full(n, 40),
               actions=np.stack([_carried(t, 0.0)[0] for t in (0.3, -0.2, 1.3, 0.1)]),
               obs=dict(object=np.stack([_carried(t, 0.0)[1] for t in (0.3, -0.2, 1.3, 0.1)])))  # fmt: skip
  turns, faces = variety.measure(batch, "turn"), variety.measure(batch)
  assert (turns["turn_short"], turns["turn_long"]) == (0.75, 0.25) and turns["thresholds_met"]["turn_each"]
  assert "turn_short" not in faces and not faces["thresholds_met"]["face_each"]  # every grasp on one face pair


def test_a_two_arm_task_is_measured_per_arm_against_its_first_grasp():
  """Transport: robot0's 10 actions against the lid's handle (one grasp: no faces), robot1's against the
  trash cube (its faces); every arm's thresholds named after it."""
  n = 4
  left, right = _carried(0.0, 0.0), _carried(0.0, np.pi / 2)  # robot0 across the lid's yaw; robot1 a quarter turn
  obj = np.zeros((n, 40, 41))
  obj[..., 14:21], obj[..., 7:14] = left[1], right[1]
  batch = dict(success=np.ones(n, bool), length=np.full(n, 40), obs=dict(object=obj),
               actions=np.broadcast_to(np.concatenate([left[0], right[0]], axis=1), (n, 40, 20)))  # fmt: skip
  m = variety.measure_task(batch, "transport")
  assert "face_0" not in m["arms"]["robot0"] and m["arms"]["robot1"]["face_1"] == 1.0
  assert m["thresholds_met"] == dict(robot0_arc_each_side=False, robot0_success=True, robot0_carry_each_side=False,
                                     robot1_arc_each_side=False, robot1_face_each=False, robot1_success=True,
                                     robot1_carry_each_side=False)  # fmt: skip


@pytest.mark.slow
def test_the_varied_transport_demonstrator_succeeds_and_arcs_both_arms(jitted_env):
  """`style=varied` on Transport: on 16 start states at least 15 succeed, each arm's approaches arc to
  both sides, and robot1 closes on both pairs of the trash cube's faces."""
  env, _, _ = jitted_env("transport")
  batch = collect.run_demos(env, make_expert("transport", "varied"), jax.random.split(jax.random.PRNGKey(3), 16),
                            progress=False)  # fmt: skip
  m = variety.measure_task(batch, "transport")
  assert m["success_rate"] >= 15 / 16
  assert min(min(a["arc_left"], a["arc_right"]) for a in m["arms"].values()) > 0.05
  assert min(m["arms"]["robot1"]["face_0"], m["arms"]["robot1"]["face_1"]) > 0.1


def test_an_unknown_demonstration_style_lists_the_known_ones():
  with pytest.raises(ValueError, match="known styles: scripted, varied"):
    make_expert("lift", "human")


def test_unknown_expert_lists_known_ones():
  with pytest.raises(ValueError, match="known scripted demonstrators: can, lift, square, transport"):
    make_expert("transpot")


@pytest.mark.slow
@pytest.mark.parametrize("task", [t for t in EXPERTS.names() if t != "lift"])  # lift: above
def test_demonstrators_succeed(task, jitted_env):
  env, _, _ = jitted_env(task)
  batch = collect.run_demos(env, make_expert(task), jax.random.split(jax.random.PRNGKey(0), 16), progress=False)
  assert batch["success"].mean() >= 0.9


def _run(env, expert, state, es, steps):
  """`steps` control steps of the batch under the demonstrator -> (state, expert state, success so far)."""

  def body(carry, _):
    state, es, done = carry
    action, es = jax.vmap(expert.act)(es, state.obs)
    state = jax.vmap(env.step)(state, action)
    return (state, es, done | (state.metrics["success"] > 0)), None

  done = jax.numpy.zeros(state.obs["object"].shape[0], bool)
  return jax.jit(lambda c: jax.lax.scan(body, c, None, length=steps)[0])((state, es, done))


@pytest.mark.slow
def test_transport_demonstrator_resumes_mid_episode(jitted_env):
  """Stopped part way (robot0 between the lid and the hammer, or at the handover), a new demonstrator
  started with `resume` from the scene alone picks the phase each arm is in and finishes the task."""
  env, _, _ = jitted_env("transport")
  expert = make_expert("transport")
  keys = jax.random.split(jax.random.PRNGKey(5), 4)
  state = jax.vmap(env.reset)(keys)
  es = jax.vmap(expert.init)(state.obs, jax.vmap(lambda k: jax.random.fold_in(k, 1))(keys))
  for steps in (140, 140):  # t = 140: the lid's part; t = 280: about the handover
    state, es, done = _run(env, expert, state, es, steps)
    assert not done.any()
    resumed = jax.vmap(lambda o, k: expert.init(o, k, resume=True))(
      state.obs, jax.random.split(jax.random.PRNGKey(9), 4)
    )
    np.testing.assert_array_equal(resumed[0].phase, jax.vmap(transport.resume0)(state.obs))
    assert (resumed[0].phase > 0).all() and (resumed[1].phase > 0).all()  # not from the start
    _, _, finished = _run(env, expert, state, resumed, env.episode_length - 280)
    assert finished.all(), (steps, resumed[0].phase, resumed[1].phase)


def test_a_resumed_expert_moves_at_constant_speed_at_once(jitted_env):
  """Resumed at every decision, a minimum-jerk start (at rest) would slow every move several-fold; a
  resumed expert's first motion is linear, the demonstrations' motions stay minimum-jerk."""
  import dataclasses

  env, reset, _ = jitted_env("lift")
  obs = reset(jax.random.PRNGKey(3)).obs
  expert = dataclasses.replace(make_expert("lift"), noise_std=0.0)

  def steps(es, n=4):
    pos = []
    for _ in range(n):
      action, es = expert.act(es, obs)
      pos.append(np.asarray(action[:3]))
    return np.linalg.norm(np.diff(np.stack(pos), axis=0), axis=-1)

  resumed = expert.init(obs, jax.random.PRNGKey(0), resume=True)  # over nothing yet: phase 1, above the cube
  assert int(resumed.phase) == 1 and bool(resumed.linear)
  linear = steps(resumed)
  assert linear.min() > 1e-3 and np.ptp(linear) < 1e-6  # the same step every step
  jerk = steps(resumed.replace(linear=np.asarray(False)))
  assert jerk[0] < 0.5 * linear[0]  # a minimum-jerk start creeps (about a quarter of the speed here)


def test_the_experts_command_saves_the_successful_demonstrations(tmp_path, capsys):
  out = str(tmp_path / "lift.hdf5")
  experts_command.FLAGS.unparse_flags()
  experts_command.main(
    ["python -m soe_jax experts", "--task=lift", "--num_episodes=2", "--backend=mujoco", f"--out={out}"]
  )
  result = json.loads(capsys.readouterr().out.splitlines()[-1])
  assert result["task"] == "lift" and result["num_episodes"] == 2 and result["backend"] == "mujoco"
  episodes, env_args = hdf5.read_episodes(out)
  assert result["num_saved"] == len(episodes) == round(2 * result["success_rate"]) and result["out"] == out
  assert env_args["soe_jax"]["env_name"] == "lift" and env_args["soe_jax"]["seed"] == 0


def test_the_experts_command_refuses_an_unknown_task_in_one_line(capsys):
  experts_command.FLAGS.unparse_flags()
  with pytest.raises(SystemExit) as exit:
    experts_command.main(["python -m soe_jax experts", "--task=stack"])
  err = capsys.readouterr().err
  assert exit.value.code == 2 and err.startswith("error: flag --task=stack") and err.count("\n") == 1

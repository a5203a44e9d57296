"""A robot's rotation conventions to rotation-6d and back (`data.rotations`), against scipy's `Rotation`
for every convention: axis-angle, quaternions in both orders, Euler angles in all 24 sequences, in
radians and degrees; and the edges (no rotation, half a turn, gimbal lock) as rotations."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from soe_jax.data import rotations
from soe_jax.data.spec import PolicySpec

TOL = 1e-6
ROT = Rotation.random(500, random_state=0)
D6 = ROT.as_matrix()[:, :2].reshape(-1, 6)  # rotation-6d: the matrix's first two rows

CONVENTIONS = (
  [("axis_angle", dict(degrees=d)) for d in (False, True)]
  + [("quaternion", dict(quaternion=o)) for o in rotations.QUAT_ORDERS]
  + [("euler", dict(euler=s, degrees=d)) for s in rotations.EULER for d in (False, True)]
)


def _ids(c):
  return "-".join([c[0], *map(str, c[1].values())]) if isinstance(c, tuple) else None


def _scipy(rot: Rotation, part: str, kw: dict) -> np.ndarray:
  """scipy's canonical values in the convention."""
  if part == "axis_angle":
    return rot.as_rotvec(degrees=kw["degrees"])
  if part == "quaternion":
    return rot.as_quat(canonical=True, scalar_first=kw["quaternion"] == "wxyz")
  return rot.as_euler(kw["euler"], degrees=kw["degrees"])


@pytest.mark.parametrize("part,kw", CONVENTIONS, ids=[_ids(c) for c in CONVENTIONS])
def test_every_convention_round_trips_as_scipy_does(part, kw):
  conv = rotations.convention(part, **kw)
  x = _scipy(ROT, part, kw)
  np.testing.assert_allclose(rotations.to_6d(x, conv), D6, atol=TOL)  # to rotation-6d as scipy's matrix
  np.testing.assert_allclose(rotations.from_6d(D6, conv), x, atol=TOL)  # back, scipy's canonical values
  np.testing.assert_allclose(rotations.from_6d(rotations.to_6d(x, conv), conv), x, atol=TOL)


def _edges() -> Rotation:
  """No rotation, tiny ones, half a turn and nearly, about axes and between them."""
  axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -2, 3]], float)
  axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
  angles = [0.0, 1e-12, 1e-7, 1e-4, 1.0, np.pi - 1e-7, np.pi]
  return Rotation.from_rotvec(np.concatenate([axes * a for a in angles]))


@pytest.mark.parametrize("part,kw", CONVENTIONS, ids=[_ids(c) for c in CONVENTIONS])
def test_the_edges_round_trip_as_rotations(part, kw):
  conv = rotations.convention(part, **kw)
  rots = [_edges()]
  if part == "euler":  # gimbal lock: the middle angle at +-pi/2 (Tait-Bryan) or 0 and pi (proper)
    seq, lock = kw["euler"], [0.0, np.pi] if kw["euler"][0] == kw["euler"][2] else [-np.pi / 2, np.pi / 2]
    angles = [[a, b, c] for b in lock for a in (-2.0, 0.0, 0.7) for c in (0.0, 1.3)]
    rots.append(Rotation.from_euler(seq, angles))
  for rot in rots:
    m = rot.as_matrix()
    back = rotations.to_matrix(rotations.from_6d(m[:, :2].reshape(-1, 6), conv), conv)
    np.testing.assert_allclose(back, m, atol=TOL)


def test_a_quaternion_of_either_sign_or_any_length_is_the_same_rotation():
  conv = rotations.convention("quaternion", quaternion="wxyz")
  q = ROT.as_quat(scalar_first=True)
  np.testing.assert_allclose(rotations.to_6d(-3.0 * q, conv), D6, atol=TOL)


def test_a_spec_converts_actions_between_the_robots_layout_and_the_policys():
  """Two arms: one axis-angle (converted), one rotation-6d already; the positions and grippers pass."""
  robot_arms = [[["position", 3], ["axis_angle", 3], ["gripper", 1]], [["position", 3], ["rotation_6d", 6]]]
  convs = rotations.arm_conventions(robot_arms)
  assert convs == [dict(part="axis_angle", convention="rotvec", degrees=False), None]
  arms = rotations.policy_arms(robot_arms, convs)
  assert arms == [[["position", 3], ["rotation_6d", 6], ["gripper", 1]], [["position", 3], ["rotation_6d", 6]]]
  spec = PolicySpec(observations={}, actions=arms, action_frame="world", control_hz=10.0, robot_rotations=convs)
  assert spec.robot_actions == robot_arms and spec.position_indices(robot=True) == [[0, 1, 2], [7, 8, 9]]
  rng = np.random.default_rng(0)
  rotvec = ROT[:4].as_rotvec()
  robot = np.concatenate([rng.normal(size=(4, 3)), rotvec, rng.uniform(size=(4, 1)), rng.normal(size=(4, 3)),
                          D6[4:8]], -1).astype(np.float32)  # fmt: skip
  policy = spec.from_robot(robot)
  assert policy.shape == (4, 19) and policy.dtype == np.float32
  np.testing.assert_allclose(policy[:, 3:9], D6[:4], atol=1e-6)
  np.testing.assert_array_equal(policy[:, 9:], robot[:, 6:])
  np.testing.assert_allclose(spec.to_robot(policy), robot, atol=1e-6)
  assert PolicySpec.from_dict(spec.to_dict()) == spec
  with pytest.raises(ValueError, match="one per arm"):
    rotations.arm_conventions([[["axis_angle", 3], ["quaternion", 4]]])
  with pytest.raises(ValueError, match="Euler sequence 'xxy'"):
    rotations.convention("euler", euler="xxy")

"""A robot of your own: a policy fitted on a LeRobotDataset, served to the robot, re-fitted on the
episodes it recorded that a person labelled successful (README, "On a real robot").

  python -m soe_jax fit --config=configs/robot.py:cpu --config.dataset.path=DATA --workdir=runs/robot
  python -m soe_jax serve --checkpoint=runs/robot/rounds/0/ckpt
  python -m soe_jax refit --workdir=runs/robot --episodes=RECORDED

Edit `dataset` below to your robot: the action's layout per arm, how each part is normalised, the
end-effector pose keys (for relative actions), an action box. Presets: `smoke`, `cpu`, `image`
(soe_jax/robot/config.py says what each does).
"""

from soe_jax.robot import config as robot_config


def get_config(arg=None):
  c = robot_config.config(arg)
  # The paper's robot: one arm, 10-d absolute actions (position, rotation-6d, gripper in metres).
  c.dataset.actions = (robot_config.ARM,)
  c.dataset.normalize.gripper = "range"  # per part: range (its range in the data) or identity
  return c

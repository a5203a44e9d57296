"""The config of a policy for a robot of one's own, fitted on files: `configs/robot.py` calls `config(arg)`.

Sections: `dataset` (where the demonstrations are and what the spec cannot read from them: the action's
layout per arm, how each part is normalised, each arm's end-effector pose, an action box, the
rotation's convention and whether the policy gets it as rotation-6d), `policy` and
`fit` (the simulated tasks' own sections, `experiment.sections`), `data` (the training buffer), `refit`
(what `refit` adds and how it fits). Presets after the colon: `smoke` (tiny, seconds), `cpu` (the
narrow UNet recipe that converged fastest on a 2-core CPU), `image` (the cameras through robomimic's
ResNet-18, narrow under `cpu`). Nothing here imports the simulator.
"""

from __future__ import annotations

import ml_collections

from soe_jax.experiment import sections
from soe_jax.policies.nets.resnet import CPU_IMAGE_WIDTHS, RESNET18_WIDTHS, SMOKE_IMAGE_WIDTHS

PRESETS = ("smoke", "cpu", "image")
# One arm's 10-d action as the paper's robot and Diffusion Policy have it.
ARM = (("position", 3), ("rotation_6d", 6), ("gripper", 1))


def normalize() -> ml_collections.ConfigDict:
  """`dataset.normalize`: one field per action part, `range` or `identity`. A part of `dataset.actions`
  not named here is normalised by its range."""
  return ml_collections.ConfigDict(
    dict(
      position="range",
      rotation_6d="identity",  # the rotation matrix's first two rows: already in [-1, 1]
      axis_angle="range",  # a rotation vector, up to pi rad in each coordinate
      quaternion="range",
      euler="range",  # up to pi rad
      gripper="range",  # a real gripper's opening in metres or counts (identity: already in [-1, 1])
    )
  )


def rotation() -> ml_collections.ConfigDict:
  """`dataset.rotation`: a robot's rotation part (an arm's `axis_angle`, `quaternion` or `euler` in
  `dataset.actions`) and its convention (`data.rotations`). to_6d: the part becomes `rotation_6d` when
  the dataset is read (the policy's, continuous, as `policy.action_frame=chunk_relative` needs) and the
  server turns every reply back into the robot's convention, as its recordings hold it."""
  return ml_collections.ConfigDict(
    dict(
      to_6d=False,
      quaternion="xyzw",  # the components' order: xyzw (scipy, ROS) or wxyz (MuJoCo, Eigen's constructor)
      euler="xyz",  # the axes, scipy's way: lowercase extrinsic (xyz: roll, pitch, yaw), uppercase intrinsic
      degrees=False,  # Euler angles and the axis-angle vector's length in degrees (else radians)
    )
  )


def base_config() -> ml_collections.ConfigDict:
  c = ml_collections.ConfigDict()
  c.seed = 0
  # path: a LeRobotDataset v3.0 directory. observations: the features the policy reads ((): every
  # `observation.*` feature). image_size: (height, width) the policy's images are resized to when read
  # ((0, 0): as stored). actions: the action feature's parts per arm, in order. normalize: per part
  # name, how the normaliser treats it (range: its range in the data, or the action box, mapped to
  # [-1, 1]; identity: left as it is, for a part already in [-1, 1]). poses: per arm {"position": key
  # or [key, offset], "orientation": key or [key, offset], "quat_order": "xyzw" | "wxyz"} (needed by
  # policy.action_frame=chunk_relative). action_box: per arm {"position": [[lo x, y, z], [hi x, y, z]]}
  # the robot may be commanded in (with policy.action_range=workspace), or (). rotation: the rotation
  # part's convention, and whether the policy gets it as rotation-6d (`rotation`).
  c.dataset = ml_collections.ConfigDict(
    dict(
      path="",
      observations=(),
      image_size=(0, 0),
      actions=(ARM,),
      normalize=normalize(),
      poses=(),
      action_box=(),
      rotation=rotation(),
    )
  )
  c.policy = sections.policy()
  c.policy.action_range = "demonstrations"  # the data's widened range, unless a box is stated
  c.fit = sections.fit()
  c.data = ml_collections.ConfigDict(dict(capacity=2048, max_length=2000, image_frames=0))
  # refit: the episodes a `refit` adds from a dataset of recorded episodes (all_successes: every
  # episode labelled successful; first_success: the first success per start state, which needs a
  # `start_state` column), and how it fits: continue from the last round's parameters for `steps` at a
  # peak lr of `lr` with the EMA carried on or restarted (`ema`), or from scratch for fit.num_steps.
  c.refit = ml_collections.ConfigDict(dict(select="all_successes", mode="continue", steps=3000, lr=3e-4, ema="carry"))
  return c


def config(arg: str | None = None) -> ml_collections.ConfigDict:
  """`base_config` with the presets in `arg` ('cpu,image')."""
  presets = [p.strip() for p in (arg or "").split(",") if p.strip()]
  unknown = [p for p in presets if p not in PRESETS]
  if unknown:
    raise ValueError(f"unknown preset {unknown[0]!r}; known presets: {', '.join(PRESETS)}")
  c = base_config()
  if "cpu" in presets:
    sections.cpu_recipe(c)
    c.fit.num_steps = 10_000
  if "smoke" in presets:
    sections.smoke_recipe(c)
    c.data.capacity = 64
    c.refit.steps = 20
  if "image" in presets:
    widths = SMOKE_IMAGE_WIDTHS if "smoke" in presets else CPU_IMAGE_WIDTHS if "cpu" in presets else RESNET18_WIDTHS
    # cameras (): every image the spec has; crop_size: a fraction of the image's side when below 1.
    c.policy.encoder = ml_collections.ConfigDict(
      dict(name="image", kwargs=dict(cameras=(), crop_size=0.9, widths=widths))
    )
    c.data.image_frames = 2_000 if "smoke" in presets else 40_000
  return c

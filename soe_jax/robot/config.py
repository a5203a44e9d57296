"""The config of a policy for a robot of one's own, fitted on files: `configs/robot.py` calls `config(arg)`.

Sections: `dataset` (where the demonstrations are and what the spec cannot read from them: the action's
layout per arm, how each part is normalised, each arm's end-effector pose, an action box, the
rotation's convention and whether the policy gets it as rotation-6d), `policy` and
`fit` (the simulated tasks' own sections, `train.sections`), `data` (the training buffer), `rounds`
(what `refit` adds and how it fits, under the simulated tasks' field names). Presets after the colon:
`smoke` (tiny, seconds), `cpu` (the narrow UNet recipe that converged fastest on a 2-core CPU, and the
bypass's KL weight and re-fit windows the simulated `cpu` preset adopted, `sections.adopted_refit`),
`image` (the cameras through robomimic's ResNet-18, narrow under `cpu`). Nothing here imports the
simulator.

What the simulated `cpu` preset's protocol (SIME's) sets and a robot's `cpu` preset does not take:
- the selection (`rounds.select`: SIME's `train_0.5`, first-success): they group tries by the simulator's
  start states; a robot's episodes have start states only where a person names them (`start_state`),
  so every labelled success is taken (`all_successes`);
- the re-fit mode (`rounds.refit`: scratch): a re-fit between sessions on the robot continues for 3k
  steps instead of repeating round 0's whole fit (`--config.rounds.refit=scratch` gives the protocol's);
- the horizons (one observation step, 20-step chunks executed whole): Diffusion Policy's real-robot
  2 / 16 / 8, which a robot's latency and control rate were tuned for; set `policy.*` to change them;
- the action range (`policy.action_range`: the task's workspace): a robot has no task workspace; the
  demonstrations' widened range, or a box stated in `dataset.action_box`.
"""

from __future__ import annotations

import ml_collections

from soe_jax.policies.nets.resnet import CPU_IMAGE_WIDTHS, RESNET18_WIDTHS, SMOKE_IMAGE_WIDTHS
from soe_jax.train import sections

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
  # rounds: the simulated tasks' field names (`experiment.presets.base_config`), those a robot's rounds
  # use: which recorded episodes a `refit` adds (`select`: all_successes, every episode labelled
  # successful; first_success, the first success per start state, which needs a `start_state` column),
  # and how it fits: continue from the last round's parameters (`refit`) for `refit_steps` at a peak lr
  # of `refit_lr` (0: fit.lr) with the EMA carried on or restarted (`refit_ema`), or from scratch for
  # fit.num_steps; its windows (`demo_fraction`, `aligned_windows`: a recorded episode's windows start
  # at its recorded decisions only, `docs/robot.md`).
  c.rounds = ml_collections.ConfigDict(
    dict(select="all_successes", refit="continue", refit_steps=3000, refit_lr=3e-4, refit_ema="carry",
         demo_fraction=0.0, aligned_windows=False)
  )  # fmt: skip
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
    sections.adopted_refit(c)
    c.fit.num_steps = 10_000
  if "smoke" in presets:
    sections.smoke_recipe(c)
    c.data.capacity = 64
    c.rounds.refit_steps = 20
  if "image" in presets:
    widths = SMOKE_IMAGE_WIDTHS if "smoke" in presets else CPU_IMAGE_WIDTHS if "cpu" in presets else RESNET18_WIDTHS
    # cameras (): every image the spec has; crop_size: a fraction of the image's side when below 1.
    c.policy.encoder = ml_collections.ConfigDict(
      dict(name="image", kwargs=dict(cameras=(), crop_size=0.9, widths=widths))
    )
    c.data.image_frames = 2_000 if "smoke" in presets else 40_000
  return c


# Fields renamed since robot configs were first saved (the simulated tasks' names since then), and
# fields added with the value that does what a saved config without them did.
RENAMED = {
  "refit.select": "rounds.select",
  "refit.mode": "rounds.refit",
  "refit.steps": "rounds.refit_steps",
  "refit.lr": "rounds.refit_lr",
  "refit.ema": "rounds.refit_ema",
}
ADDED = {"rounds.demo_fraction": 0.0, "rounds.aligned_windows": False}


def upgrade(saved: dict) -> dict:
  """A saved config (`config.json`) in today's fields: renamed ones under their new names, added ones
  at the value the config was fitted with."""
  saved = {k: dict(v) if isinstance(v, dict) else v for k, v in saved.items()}
  for old, new in RENAMED.items():
    (section, name), (new_section, new_name) = old.split("."), new.split(".")
    if name in saved.get(section, {}):
      saved.setdefault(new_section, {})[new_name] = saved[section].pop(name)
      if not saved[section]:
        del saved[section]
  for field, value in ADDED.items():
    section, name = field.split(".")
    if section in saved:
      saved[section].setdefault(name, value)
  return saved


def upgrade_field(name: str) -> str:
  """A field's name as it was saved -> today's ('refit.steps' -> 'rounds.refit_steps')."""
  return RENAMED.get(name, name)

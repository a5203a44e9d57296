"""The steering page's frames, drawn by a child process: the picture follows the joints, a camera the
model lacks is refused with the child's reason, and a closed renderer says so."""

import io
import os

import matplotlib.image
import mujoco
import numpy as np
import pytest

pytestmark = pytest.mark.skipif(
  not any(
    os.path.exists(os.path.join(d, "libEGL_mesa.so.0")) for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/lib")
  ),
  reason="needs Mesa's EGL: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri",
)

SCENE = """<mujoco><worldbody><light pos="0 0 2"/>
  <camera name="front" pos="0 -1 0.2" xyaxes="1 0 0 0 0 1"/>
  <body><joint name="slide" type="slide" axis="1 0 0"/><geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></body>
</worldbody></mujoco>"""


def _red_columns(png: bytes) -> np.ndarray:
  image = matplotlib.image.imread(io.BytesIO(png))
  assert image.shape[:2] == (64, 64)
  red = (image[..., 0] > 0.5) & (image[..., 1] < 0.3)
  return np.flatnonzero(red.any(axis=0))


def test_frames_follow_the_joints_and_errors_name_their_cause():
  from soe_jax.steer.frames import FrameError, Frames

  model = mujoco.MjModel.from_xml_string(SCENE)
  with Frames(model, 64, "front") as frames:
    centre = _red_columns(frames.png(np.zeros(1)))
    right = _red_columns(frames.png(np.array([0.2])))
    assert len(centre) and len(right) and right.mean() > centre.mean() + 5  # the box moved right
  with pytest.raises(FrameError, match="closed"):
    frames.png(np.zeros(1))
  with pytest.raises(FrameError, match="nosuchcamera"):
    Frames(model, 64, "nosuchcamera")

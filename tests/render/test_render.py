"""The renderer pool: the picture follows the joints, a batch split across processes comes back in
order and equal to one process's, a camera the model lacks is refused naming the model's cameras, and
a closed renderer says so."""

import os

import mujoco
import numpy as np
import pytest

from soe_jax.render.pool import Renderer, RenderError

needs_egl = pytest.mark.skipif(
  not any(
    os.path.exists(os.path.join(d, "libEGL_mesa.so.0")) for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/lib")
  ),
  reason="needs Mesa's EGL: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri",
)
pytestmark = needs_egl

SCENE = """<mujoco><worldbody><light pos="0 0 2"/>
  <camera name="front" pos="0 -1 0.2" xyaxes="1 0 0 0 0 1"/>
  <camera name="top" pos="0 0 1" xyaxes="1 0 0 0 1 0"/>
  <site name="marker" pos="0 -0.5 0.2" size="0.05" rgba="0 1 0 1"/>
  <body><joint name="slide" type="slide" axis="1 0 0"/><geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></body>
</worldbody></mujoco>"""


def _red_columns(image: np.ndarray) -> np.ndarray:
  red = (image[..., 0] > 128) & (image[..., 1] < 80)
  return np.flatnonzero(red.any(axis=0))


def test_images_follow_joints_and_split_batches_return_in_order():
  model = mujoco.MjModel.from_xml_string(SCENE)
  qpos = np.linspace(-0.2, 0.2, 5)[:, None]
  with (
    Renderer(model, ["front", "top"], 48, 64, processes=2) as two,
    Renderer(model, ["front"], 48, 64, processes=1) as one,
  ):
    images = two.render(qpos)
    assert images["front"].shape == (5, 48, 64, 3) and images["front"].dtype == np.uint8
    assert images["top"].shape == (5, 48, 64, 3)
    centres = [_red_columns(im).mean() for im in images["front"]]
    assert np.all(np.diff(centres) > 3)  # the box moves right in the picture as the joint slides
    np.testing.assert_array_equal(one.render(qpos)["front"], images["front"])  # the same pixels from one process
    np.testing.assert_array_equal(two.render(qpos[2])["front"], images["front"][2])  # one state, no batch axis
    assert not ((images["front"][..., 1] > 200) & (images["front"][..., 0] < 80)).any()  # sites are not drawn
  with pytest.raises(RenderError, match="closed"):
    two.render(qpos)


def test_unknown_cameras_name_the_known_ones():
  model = mujoco.MjModel.from_xml_string(SCENE)
  with pytest.raises(ValueError, match="unknown camera 'nosuchcamera'; the model's cameras: front, top"):
    Renderer(model, ["nosuchcamera"], 32)


def test_a_renderer_that_cannot_start_says_why(monkeypatch):
  monkeypatch.setenv("MUJOCO_GL", "nosuchgl")  # the child's mujoco refuses it on import
  model = mujoco.MjModel.from_xml_string(SCENE)
  with pytest.raises(RenderError, match="(?s)exited with status.*nosuchgl"):
    Renderer(model, ["front"], 32).render(np.zeros((1, 1)))

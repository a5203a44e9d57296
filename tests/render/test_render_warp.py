"""MuJoCo Warp's batch renderer (on Warp's CPU device here): Lift's cameras drawn as OpenGL draws them
(the in-hand camera without the hand's geoms inside its near plane), batches of any size in order, and
`env.renderer` choosing it."""

import numpy as np
import pytest

from soe_jax.render import choice as render_choice
from tests.render.test_render import needs_egl

pytest.importorskip("warp", reason="needs warp-lang: pip install 'soe_jax[gpu]'")
pytestmark = needs_egl


@pytest.fixture(scope="module")
def lift_states():
  import jax

  from soe_jax.envs.registry import make_env

  env = make_env("lift", obs_mode="image", renderer="gl")
  state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 5))
  qpos = np.array(state.pipeline_state.qpos)
  qpos[1, :7] += 0.3  # one arm elsewhere
  yield env, qpos, env.draw(qpos)
  env.renderer.close()


def test_warp_draws_lifts_cameras_as_opengl_does(lift_states):
  from soe_jax.render import warp_renderer

  env, qpos, gl = lift_states
  assert warp_renderer.near_geoms(env.mj_model, "agentview") == []
  hand = warp_renderer.near_geoms(env.mj_model, "robot0_eye_in_hand")
  assert hand and {env.mj_model.body(env.mj_model.geom_bodyid[g]).name for g in hand} <= {"link7", "right_gripper"}
  with warp_renderer.WarpRenderer(env.mj_model, env.cameras, env.image_size, device="cpu") as warp:
    images = warp.render(qpos)
    for camera in env.cameras:
      drawn, reference = images[camera], gl[f"{camera}_image"]
      assert drawn.shape == reference.shape and drawn.dtype == np.uint8
      assert np.abs(drawn.astype(int) - reference).mean() < 3, camera  # anti-aliasing and shading apart
    assert np.abs(images["agentview"][1].astype(int) - images["agentview"][0]).mean() > 1  # the arm moved
    np.testing.assert_array_equal(warp.render(qpos[3])["agentview"], images["agentview"][3])  # one state, no batch


def test_batches_larger_than_a_block_come_back_in_order(lift_states, monkeypatch):
  from soe_jax.render import warp_renderer

  env, qpos, _ = lift_states
  with warp_renderer.WarpRenderer(env.mj_model, ["agentview"], 32, device="cpu") as warp:
    whole = warp.render(qpos)["agentview"]  # one padded block of 8
    monkeypatch.setattr(warp_renderer, "BLOCK", 2)
    np.testing.assert_array_equal(warp.render(qpos)["agentview"], whole)  # blocks of 2, 2 and 1 (padded)
  with pytest.raises(RuntimeError, match="closed"):
    warp.render(qpos)


def test_env_renderer_chooses_the_renderer():
  from soe_jax.envs.registry import make_env
  from soe_jax.render.warp_renderer import WarpRenderer

  assert render_choice.resolve("auto") == "gl"  # no CUDA GPU here
  with pytest.raises(ValueError, match="unknown renderer 'vulkan'; known renderers: auto, gl, warp"):
    render_choice.resolve("vulkan")
  env = make_env("lift", obs_mode="image", renderer="warp")
  assert isinstance(env.renderer, WarpRenderer)

"""The image encoder: robomimic's size per camera, crops, and use as the policy's encoder."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax.policies.nets import resnet


def test_camera_encoder_size_and_output():
  enc = resnet.CameraEncoder()
  shapes = jax.eval_shape(enc.init, jax.random.PRNGKey(0), jnp.zeros((1, 76, 76, 3)))
  params = sum(int(np.prod(x.shape)) for x in jax.tree.leaves(shapes))
  assert 11.1e6 < params < 11.3e6  # robomimic: about 11.20M per camera


def test_random_crop_in_training_centre_crop_in_evaluation():
  images = jnp.arange(2 * 3 * 84 * 84, dtype=jnp.float32).reshape(2, 3, 84, 84, 1)
  centre = resnet.crop(images, 76, train=False)
  np.testing.assert_array_equal(centre, images[:, :, 4:80, 4:80])
  a = resnet.crop(images, 76, train=True, key=jax.random.PRNGKey(0))
  b = resnet.crop(images, 76, train=True, key=jax.random.PRNGKey(1))
  assert a.shape == (2, 3, 76, 76, 1)
  assert not np.array_equal(a, b)
  offsets = {(int(x[0, 0, 0]) % (84 * 84)) for x in np.asarray(a).reshape(6, 76, 76, 1)}
  assert len(offsets) > 1  # independent per image


@pytest.mark.slow
def test_image_encoder_concatenates_cameras_and_lowdim_per_frame():
  enc = resnet.ImageEncoder(cameras=("agentview_image",), crop_size=24)
  obs = {"images": {"agentview_image": jnp.zeros((2, 2, 28, 28, 3))}, "lowdim": jnp.ones((2, 2, 9))}
  out, params = enc.init_with_output({"params": jax.random.PRNGKey(0), "crop": jax.random.PRNGKey(1)}, obs, train=True)
  assert out.shape == (2, 2 * (64 + 9))
  np.testing.assert_array_equal(out.reshape(2, 2, 73)[..., 64:], 1.0)


def test_im2col_convolutions_match_xlas():
  x = jax.random.normal(jax.random.PRNGKey(0), (2, 19, 19, 5))
  for k, stride, pad in ((7, 2, 3), (3, 1, 1), (3, 2, 1), (1, 2, 0)):
    conv = resnet.Conv(4, k, stride, padding=pad)
    params = jax.jit(conv.init)(jax.random.PRNGKey(1), x)
    w = params["params"]["kernel"]
    assert w.shape == (k, k, 5, 4)  # flax's nn.Conv layout
    reference = jax.lax.conv_general_dilated(
      x, w, (stride, stride), [(pad, pad)] * 2, dimension_numbers=("NHWC", "HWIO", "NHWC")
    )
    np.testing.assert_allclose(jax.jit(conv.apply)(params, x), reference, rtol=1e-4, atol=1e-4)


def test_shared_trunk_encodes_each_camera_as_its_own_trunk_would():
  cams = ("agentview_image", "robot0_eye_in_hand_image")
  obs = {
    "images": {c: jax.random.uniform(jax.random.PRNGKey(i), (2, 1, 20, 20, 3)) for i, c in enumerate(cams)},
    "lowdim": jnp.ones((2, 1, 3)),
  }
  shared = resnet.ImageEncoder(cameras=cams, crop_size=16, widths=(8, 8, 8, 8), shared=True)
  params = jax.jit(shared.init)(jax.random.PRNGKey(0), obs)  # (compiled: eagerly, each layer compiles alone)
  assert list(params["params"]) == ["camera"]  # one trunk, not one per camera
  out = jax.jit(shared.apply)(params, obs)
  two = resnet.ImageEncoder(cameras=cams, crop_size=16, widths=(8, 8, 8, 8))
  same = {"params": {f"camera_{i}": params["params"]["camera"] for i in range(2)}}
  np.testing.assert_allclose(out, jax.jit(two.apply)(same, obs), rtol=1e-5, atol=1e-6)
  assert out.shape == (2, 2 * 64 + 3)

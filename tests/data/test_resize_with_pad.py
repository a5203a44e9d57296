"""Resize-with-pad, the rule that brings a camera to a policy's size when a dataset is read and when the
server receives it: the aspect ratio kept, bilinear, centred on black, the odd pixel below or right; a
camera of the target's aspect ratio resized exactly as a plain bilinear resize."""

import numpy as np
import pytest
from PIL import Image

from soe_jax.data.images import resize_with_pad, resized_shape


def _image(h, w, seed=0):
  return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


def _openpi(shape, size):
  """openpi-client's `image_tools._resize_with_pad_pil` arithmetic: (resized height, width, top, left)."""
  (h, w), (th, tw) = shape, size
  ratio = max(w / tw, h / th)
  rh, rw = int(h / ratio), int(w / ratio)
  return rh, rw, max(0, int((th - rh) / 2)), max(0, int((tw - rw) / 2))


def test_a_wide_camera_is_centred_between_black_bands():
  img = _image(216, 288)
  out = resize_with_pad(img, (84, 84))
  assert out.shape == (84, 84, 3) and out.dtype == np.uint8
  np.testing.assert_array_equal(out[10:73], np.asarray(Image.fromarray(img).resize((84, 63), Image.BILINEAR)))
  assert not out[:10].any() and not out[73:].any()  # 21 rows of padding: 10 above, 11 below
  assert _openpi((216, 288), (84, 84)) == (63, 84, 10, 0)  # openpi's own numbers for this camera


def test_a_tall_camera_is_padded_left_and_right():
  img = _image(100, 41, seed=1)
  out = resize_with_pad(img, (50, 50))
  rh, rw = resized_shape((100, 41), (50, 50))
  assert (rh, rw) == (50, 21)  # 20.5 rounded up: openpi truncates to 20
  np.testing.assert_array_equal(out[:, 14:35], np.asarray(Image.fromarray(img).resize((21, 50), Image.BILINEAR)))
  assert not out[:, :14].any() and not out[:, 35:].any()


@pytest.mark.parametrize("shape,size", [((216, 288), (96, 128)), ((216, 288), (84, 112)), ((480, 640), (84, 112)),
                                        ((32, 48), (64, 96))])  # fmt: skip
def test_the_target_s_aspect_ratio_is_a_plain_bilinear_resize(shape, size):
  img = _image(*shape)
  plain = np.asarray(Image.fromarray(img).resize((size[1], size[0]), Image.BILINEAR))
  np.testing.assert_array_equal(resize_with_pad(img, size), plain)  # (openpi's truncation pads 216 x 288 to 84 x 111)


def test_the_policy_s_size_as_it_is_and_leading_axes_kept():
  img = _image(84, 84)
  assert resize_with_pad(img, (84, 84)) is img
  stack = np.stack([_image(30, 40, seed=s) for s in range(6)]).reshape(2, 3, 30, 40, 3)
  out = resize_with_pad(stack, (12, 12))
  assert out.shape == (2, 3, 12, 12, 3)
  np.testing.assert_array_equal(out[1, 2], resize_with_pad(stack[1, 2], (12, 12)))
  with pytest.raises(ValueError, match=r"cannot resize images of shape \[0, 40, 3\] to 12 x 12"):
    resize_with_pad(np.zeros((0, 40, 3), np.uint8), (12, 12))

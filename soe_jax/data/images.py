"""Camera images brought to a policy's size, one rule for the fit's reading and the server: openpi's
`image_tools.resize_with_pad` (openpi-client, after `tf.image.resize_with_pad`). The image keeps its
aspect ratio: it is resized with PIL's bilinear filter until it fills the target's height or width,
then centred on a black (zero) canvas of the target's size, the odd pixel of padding below or to the
right. An image of the target's size is returned as it is.

One difference from openpi: the resized side is rounded to the nearest pixel, where openpi truncates
its float quotient. So a camera of the target's aspect ratio fills the target exactly (openpi turns
216 x 288 into 84 x 111 and a column of black for an 84 x 112 target), and is resized exactly as a
plain bilinear resize would.
"""

from __future__ import annotations

import numpy as np
from PIL import Image


def resized_shape(shape: tuple[int, int], size: tuple[int, int]) -> tuple[int, int]:
  """(height, width) an image of `shape` is resized to before its padding to `size`, both (height, width)."""
  (h, w), (th, tw) = shape, size
  if w * th >= h * tw:  # as wide as the target or wider: it fills the target's width
    return max(1, (2 * h * tw + w) // (2 * w)), tw
  return th, max(1, (2 * w * th + h) // (2 * h))


def resize_with_pad(images: np.ndarray, size: tuple[int, int]) -> np.ndarray:
  """(..., H, W, 3) uint8 -> (..., *size, 3): each image resized keeping its aspect ratio and padded
  with black to `size` (height, width), centred; as it is when already of that size."""
  images = np.asarray(images)
  size = (int(size[0]), int(size[1]))
  if images.shape[-3:-1] == size:
    return images
  if images.ndim < 3 or min(images.shape[-3:-1]) < 1 or min(size) < 1:
    raise ValueError(f"cannot resize images of shape {list(images.shape)} to {size[0]} x {size[1]}")
  rh, rw = resized_shape(images.shape[-3:-1], size)
  top, left = (size[0] - rh) // 2, (size[1] - rw) // 2
  flat = images.reshape(-1, *images.shape[-3:])
  out = np.zeros((len(flat), *size, images.shape[-1]), images.dtype)
  for i, img in enumerate(flat):
    out[i, top : top + rh, left : left + rw] = np.asarray(Image.fromarray(img).resize((rw, rh), Image.BILINEAR))
  return out.reshape(*images.shape[:-3], *out.shape[1:])

"""robomimic's image encoder as Diffusion Policy's hybrid policy uses it (`shared/specs/diffusion_policy.md` 5):
per camera a ResNet-18 trunk (avgpool and fc removed, random init) with every BatchNorm replaced by
GroupNorm(C // 16 groups), spatial softmax to 32 keypoints (expected x, y over a [-1, 1] grid),
Linear(64, 64) and a ReLU. Random crop (76 of 84 by default) in training, centre crop in evaluation,
drawn independently per image. Images arrive in [0, 1] and are scaled to [-1, 1]. NHWC.

Convolutions are im2col + one matrix product: inside a compiled loop (a fit chunk's `lax.scan`),
XLA:CPU runs its own 2-D convolutions about 40x slower than outside one, while matrix products keep
their speed (measured here: ResNet-18's trunk on 64 crops, forward and backward, 37.7 s in a scan
with XLA's convolutions against 0.92 s this way; BENCHMARKS.md).

`widths` are the channels of the stem and the four stages (ResNet-18's 64, 128, 256, 512 by default);
narrower ones make the same architecture affordable on a CPU (`bench encoder` times both)."""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp


def _gn(x):
  return nn.GroupNorm(num_groups=max(1, x.shape[-1] // 16), epsilon=1e-5)(x)


def _shifted(x, k: int, stride: int, pad: int) -> list:
  """The k x k strided views of (..., H, W, C) zero-padded by `pad`, tap-major: k * k arrays
  (..., H', W', C)."""
  h_out = (x.shape[-3] + 2 * pad - k) // stride + 1
  w_out = (x.shape[-2] + 2 * pad - k) // stride + 1
  xp = jnp.pad(
    x,
    [(0, 0)] * (x.ndim - 3) + [(pad, pad), (pad, pad), (0, 0)],
  )
  span_h, span_w = stride * (h_out - 1) + 1, stride * (w_out - 1) + 1
  return [xp[..., i : i + span_h : stride, j : j + span_w : stride, :] for i in range(k) for j in range(k)]


class Conv(nn.Module):
  """A k x k convolution without bias (NHWC) as im2col + one matrix product; its kernel is stored
  (k, k, in, out) and initialised as flax's `nn.Conv` does."""

  features: int
  kernel_size: int
  stride: int = 1
  padding: int = 0

  @nn.compact
  def __call__(self, x):
    k, c = self.kernel_size, x.shape[-1]
    w = self.param("kernel", nn.initializers.lecun_normal(), (k, k, c, self.features))
    if k == 1:
      return x[..., :: self.stride, :: self.stride, :] @ w[0, 0]
    patches = jnp.concatenate(_shifted(x, k, self.stride, self.padding), axis=-1)  # (..., H', W', k k C)
    return patches @ w.reshape(k * k * c, self.features)


class BasicBlock(nn.Module):
  features: int
  stride: int = 1

  @nn.compact
  def __call__(self, x):
    h = Conv(self.features, 3, self.stride, padding=1)(x)
    h = jax.nn.relu(_gn(h))
    h = _gn(Conv(self.features, 3, padding=1)(h))
    if self.stride != 1 or x.shape[-1] != self.features:
      x = _gn(Conv(self.features, 1, self.stride)(x))
    return jax.nn.relu(h + x)


RESNET18_WIDTHS = (64, 128, 256, 512)
# The trunk under the `cpu` presets, simulated and robot (the image recipe Lift's screen chose:
# BENCHMARKS.md, "The image recipe under the picked protocol"), and under `smoke` (tests).
CPU_IMAGE_WIDTHS = (8, 16, 32, 64)
SMOKE_IMAGE_WIDTHS = (8, 8, 16, 16)


class ResNet18Trunk(nn.Module):
  widths: Sequence[int] = RESNET18_WIDTHS

  @nn.compact
  def __call__(self, x):
    x = Conv(self.widths[0], 7, 2, padding=3)(x)
    x = jax.nn.relu(_gn(x))
    x = nn.max_pool(x, (3, 3), (2, 2), padding=((1, 1), (1, 1)))
    for i, f in enumerate(self.widths):
      x = BasicBlock(f, 1 if i == 0 else 2)(x)
      x = BasicBlock(f)(x)
    return x


class SpatialSoftmax(nn.Module):
  num_keypoints: int = 32

  @nn.compact
  def __call__(self, x):
    h, w = x.shape[-3], x.shape[-2]
    logits = nn.Conv(self.num_keypoints, (1, 1))(x)  # (..., H, W, K)
    logits = logits.reshape(x.shape[:-3] + (h * w, self.num_keypoints))
    attn = jax.nn.softmax(logits, axis=-2)
    gy, gx = jnp.meshgrid(jnp.linspace(-1, 1, h), jnp.linspace(-1, 1, w), indexing="ij")
    pos = jnp.stack([gx.ravel(), gy.ravel()], -1)  # (H*W, 2): x then y
    keypoints = jnp.einsum("...nk,nc->...kc", attn, pos)
    return keypoints.reshape(x.shape[:-3] + (2 * self.num_keypoints,))


class CameraEncoder(nn.Module):
  feature_dim: int = 64
  widths: Sequence[int] = RESNET18_WIDTHS

  @nn.compact
  def __call__(self, image):
    x = SpatialSoftmax()(ResNet18Trunk(tuple(self.widths))(image))
    return jax.nn.relu(nn.Dense(self.feature_dim)(x))


def crop_shape(size, h: int, w: int) -> tuple[int, int]:
  """A crop `size` for (h, w) images: an int (a square), (height, width), or a fraction (< 1) of each side."""
  if isinstance(size, float) and size < 1:
    return max(1, int(round(size * h))), max(1, int(round(size * w)))
  ch, cw = (int(size), int(size)) if isinstance(size, (int, float)) else (int(size[0]), int(size[1]))
  if ch > h or cw > w:
    raise ValueError(f"a {ch} x {cw} crop of {h} x {w} images")
  return ch, cw


def crop(images, size, train: bool, key=None):
  """(..., H, W, C) -> (..., ch, cw, C) (`crop_shape(size)`): uniform random offsets per image in
  training, centre otherwise."""
  h, w = images.shape[-3], images.shape[-2]
  ch, cw = crop_shape(size, h, w)
  if not train:
    top, left = (h - ch) // 2, (w - cw) // 2
    return images[..., top : top + ch, left : left + cw, :]
  lead = images.shape[:-3]
  flat = images.reshape((-1,) + images.shape[-3:])
  k_top, k_left = jax.random.split(key)
  tops = jax.random.randint(k_top, (flat.shape[0],), 0, h - ch + 1)
  lefts = jax.random.randint(k_left, (flat.shape[0],), 0, w - cw + 1)
  out = jax.vmap(lambda im, top, left: jax.lax.dynamic_slice(im, (top, left, 0), (ch, cw, im.shape[-1])))(
    flat, tops, lefts
  )
  return out.reshape(lead + out.shape[1:])


class ImageEncoder(nn.Module):
  """obs {"images": {camera: (B, To, H, W, 3) in [0, 1]}, "lowdim": (B, To, D) normalised} -> (B, To * (64 n_cams + D)).

  Cameras are encoded in the order of `cameras`, then the low-dim vector, per frame, frames oldest first.
  `shared`: one trunk for every camera (the cameras' crops as one batch; robomimic's default is a trunk per
  camera, which Diffusion Policy keeps) instead of one each."""

  cameras: Sequence[str] = ("agentview_image", "robot0_eye_in_hand_image")
  crop_size: int | float | Sequence[int] = 76  # `crop_shape`
  widths: Sequence[int] = RESNET18_WIDTHS
  shared: bool = False

  @nn.compact
  def __call__(self, obs, train: bool = False):
    crops = []
    for cam in self.cameras:
      key = self.make_rng("crop") if train else None
      crops.append(crop(obs["images"][cam], self.crop_size, train, key) * 2.0 - 1.0)
    lead = crops[0].shape[:-3]
    if self.shared:  # every camera's frames as one batch through one trunk
      flat = jnp.concatenate([c.reshape((-1,) + c.shape[-3:]) for c in crops])
      out = CameraEncoder(widths=tuple(self.widths), name="camera")(flat).reshape((len(crops),) + lead + (-1,))
      feats = list(out)
    else:  # frames as one batch per camera, as Diffusion Policy does
      feats = [
        CameraEncoder(widths=tuple(self.widths), name=f"camera_{i}")(c.reshape((-1,) + c.shape[-3:])).reshape(
          lead + (-1,)
        )
        for i, c in enumerate(crops)
      ]
    per_frame = jnp.concatenate(feats + [obs["lowdim"]], axis=-1)
    return per_frame.reshape(per_frame.shape[:-2] + (-1,))

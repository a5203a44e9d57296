"""PyTorch reference timings for the fit and sample benchmarks, measured on the same machine.

A line-for-line PyTorch port of Diffusion Policy's ConditionalUnet1D (`shared/specs/diffusion_policy.md`
1: Conv1d-GroupNorm-Mish blocks, FiLM scale and bias, ConvTranspose1d upsampling), eager mode, float32,
random data in memory, no EMA; the fit step is forward, epsilon MSE, backward and AdamW; the sample is
DDIM with clipping (diffusers' update rule written out). Needs `pip install torch` (not a dependency);
`python -m soe_jax bench torch` runs it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

from soe_jax.runtime.errors import UserError


def build(torch, nn, down_dims, dsed, input_dim=10, cond_dim=46, k=5, groups=8):
  F = nn.functional

  class Block(nn.Module):
    def __init__(self, i, o):
      super().__init__()
      self.conv, self.norm = nn.Conv1d(i, o, k, padding=k // 2), nn.GroupNorm(groups, o)

    def forward(self, x):
      return F.mish(self.norm(self.conv(x)))

  class Res(nn.Module):
    def __init__(self, i, o, c):
      super().__init__()
      self.b1, self.b2, self.o = Block(i, o), Block(o, o), o
      self.film = nn.Sequential(nn.Mish(), nn.Linear(c, 2 * o))
      self.res = nn.Conv1d(i, o, 1) if i != o else nn.Identity()

    def forward(self, x, cond):
      h = self.b1(x)
      f = self.film(cond).reshape(-1, 2, self.o, 1)
      h = self.b2(f[:, 0] * h + f[:, 1])
      return h + self.res(x)

  class Unet(nn.Module):
    def __init__(self):
      super().__init__()
      self.step = nn.Sequential(nn.Linear(dsed, 4 * dsed), nn.Mish(), nn.Linear(4 * dsed, dsed))
      c = dsed + cond_dim
      dims = [input_dim] + list(down_dims)
      pairs = list(zip(dims[:-1], dims[1:]))
      self.down = nn.ModuleList(
        [
          nn.ModuleList([Res(i, o, c), Res(o, o, c), nn.Conv1d(o, o, 3, 2, 1) if n < len(pairs) - 1 else nn.Identity()])
          for n, (i, o) in enumerate(pairs)
        ]
      )
      self.mid = nn.ModuleList([Res(dims[-1], dims[-1], c), Res(dims[-1], dims[-1], c)])
      self.up = nn.ModuleList(
        [
          nn.ModuleList([Res(2 * o, i, c), Res(i, i, c), nn.ConvTranspose1d(i, i, 4, 2, 1)])
          for i, o in reversed(pairs[1:])
        ]
      )
      self.final = nn.Sequential(Block(down_dims[0], down_dims[0]), nn.Conv1d(down_dims[0], input_dim, 1))

    def forward(self, x, t, g):
      half = dsed // 2
      freqs = torch.exp(torch.arange(half) * -(math.log(10000) / (half - 1)))
      emb = t[:, None].float() * freqs[None]
      cond = torch.cat([self.step(torch.cat([emb.sin(), emb.cos()], -1)), g], -1)
      x = x.moveaxis(-1, -2)
      skips = []
      for r1, r2, down in self.down:
        x = r2(r1(x, cond), cond)
        skips.append(x)
        x = down(x)
      for r in self.mid:
        x = r(x, cond)
      for r1, r2, up in self.up:
        x = up(r2(r1(torch.cat([x, skips.pop()], 1), cond), cond))
      return self.final(x).moveaxis(-1, -2)

  return Unet()


def run(
  down_dims: Sequence[int] = (256, 512, 1024), step_embed_dim: int = 256, batch: int = 256, threads: int = 2,
  steps: int = 5,
) -> dict:  # fmt: skip
  """The fit step (`steps` timed after 2 untimed, at `batch`) and one DDIM chunk's sampling (10 steps,
  the median of 20) of the UNet with widths `down_dims`, on `threads` CPU threads."""
  try:
    import torch  # here, not at the top: torch is an optional extra, not a dependency
    from torch import nn
  except ImportError as e:
    raise UserError("the torch reference needs PyTorch: pip install torch") from e

  torch.set_num_threads(threads)
  dims = [int(d) for d in down_dims]
  net = build(torch, nn, dims, step_embed_dim)
  params = sum(p.numel() for p in net.parameters())
  opt = torch.optim.AdamW(net.parameters(), lr=1e-4, betas=(0.95, 0.999), eps=1e-8, weight_decay=1e-6)
  b = batch
  x, g = torch.randn(b, 16, 10), torch.randn(b, 46)

  def fit_step():
    t = torch.randint(0, 100, (b,))
    eps = torch.randn_like(x)
    loss = ((net(x + eps, t, g) - eps) ** 2).mean()
    opt.zero_grad()
    loss.backward()
    opt.step()

  for _ in range(2):
    fit_step()
  start = time.perf_counter()
  for _ in range(steps):
    fit_step()
  fit_s = (time.perf_counter() - start) / steps

  betas = [
    min(
      1
      - math.cos(((i + 1) / 100 + 0.008) / 1.008 * math.pi / 2) ** 2
      / math.cos((i / 100 + 0.008) / 1.008 * math.pi / 2) ** 2,
      0.999,
    )
    for i in range(100)
  ]
  ac = torch.cumprod(1 - torch.tensor(betas), 0)

  @torch.no_grad()
  def sample():
    s = torch.randn(1, 16, 10)
    for t in range(90, -1, -10):
      eps = net(s, torch.tensor([t]), g[:1])
      ab, ab_prev = ac[t], (ac[t - 10] if t >= 10 else torch.tensor(1.0))
      x0 = ((s - (1 - ab).sqrt() * eps) / ab.sqrt()).clamp(-1, 1)
      s = ab_prev.sqrt() * x0 + (1 - ab_prev).sqrt() * eps
    return s

  net.eval()
  for _ in range(3):
    sample()
  times = []
  for _ in range(20):
    start = time.perf_counter()
    sample()
    times.append(time.perf_counter() - start)
  times.sort()
  return dict(
    bench="torch_reference",
    torch=torch.__version__,
    threads=threads,
    down_dims=dims,
    batch=b,
    params=params,
    fit_ms_per_step=round(fit_s * 1000, 1),
    ddim10_ms_per_chunk=round(times[len(times) // 2] * 1000, 2),
  )

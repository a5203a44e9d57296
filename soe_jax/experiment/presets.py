"""The config's fields at paper scale (`base_config`) and the presets every config file shares:
`configs/<task>.py[:PRESETS]`, and a user's own config file, call `apply_presets(base_config(...), arg)`.

`python -m soe_jax run --config=configs/TASK.py:cpu,soe` runs round 0 (scripted demonstrations, the
round-0 fit with the VIB bypass, evaluation on 200 fixed start states) and one round of exploration
(100 start states x 5 tries) -> keep each state's first success -> re-fit -> evaluate (the same
states with the same sampling keys), leaving metrics.jsonl, report.md, outcomes.json and plots in
runs/TASK-METHOD-seed<k>/. Round 0 is shared by every method run beside it.

Presets are comma-separated after the colon, e.g. `configs/square.py:cpu` or
`configs/square.py:head=flow_unet,smoke`:
- `smoke`: tiny networks, two short rounds, seconds once compiled (for tests);
- `cpu`: the protocol docs/protocol.md picked (RESULTS.md, "Applying the rule"): SIME's
  (`protocol=sime`: one observation step, 20-step chunks executed whole, `train_0.5` selection, one
  round re-trained from fresh parameters with round 0's recipe) on varied demonstrations
  (`style=varied`), each task's number of them calibrated to a round 0 in 20-80% (its config says
  which); the recipe that converged fastest on a 2-core CPU: the narrow UNet 32/64/128 at AdamW 1e-3
  and batch 64, 10k round-0 steps or the task's own; and what "why own successes hurt" adopted: the
  bypass's KL weight 1e-5 (the paper's 1e-3 otherwise) and re-fit windows aligned to the recorded
  decisions of the episodes the policy collected itself (under `protocol=continued`, the first
  campaigns' protocol, a re-fit continues for 3k steps at 3e-4 with the EMA carried on);
- `quick`: `cpu` with every fit shortened to the task's quick steps (Lift's alone: `configs/lift.py`), 100
  evaluation start states and 50 exploration start states (x 5 tries): the whole method in about ten
  minutes on 2 cores, a first run to read beside the committed campaign of the same preset
  (`analysis/context.py`, in the run's report);
- none: paper scale (Diffusion Policy's low-dim UNet, 25k steps of AdamW 3e-4 at batch 256, DDIM-10,
  3 rounds), for accelerators (there with `--config.env.backend=mujoco`: MJX compiles and steps
  these contact-rich scenes slowly even on an H100; BENCHMARKS.md);
- the method: `dp`, `sime`, `soe` or `soe_steer` (`method`, and `explore.strategy`: the strategy of
  that name with its settings), or `control` (each round re-fits on the previous round's data alone,
  with the same budget: no exploration, no new episodes);
- `expert_data`, beside a method: an oracle arm that explores as the method does and then trains on
  the scripted demonstrator's episodes from the start states the method kept (`method` becomes
  `<method>-expert_data`, `rounds.new_data` `expert`);
- what an exploring method keeps and how it explores, beside it (each adds to `method`, e.g.
  `soe,select=shortest_success` is `soe-select_shortest_success`): `select=RULE` (`rounds.select`),
  `length_cap=X` (`rounds.length_cap`: only successes no longer than X times the demonstrations' mean
  length), `alpha=X` and `hold=N` (the strategy's exploration scale; `soe`'s decisions per draw of
  its latent noise), `beta=X` (the bypass's KL weight `policy.bypass.beta`, the KL ablation: the
  arm fits a round 0 of its own), `demo_fraction=X` and `aligned=true|false` (the re-fit's sampling);
  a variant names the arm only where it changes its field (`aligned=false` under `cpu`:
  `soe-aligned_false`; `beta=1e-05` under `cpu`: plain `soe`);
- with any method, the control too, each with a round 0 of its own: `range=demonstrations`
  (`policy.action_range`), `frame=chunk_relative` (`policy.action_frame`, relative actions, which
  need `range=demonstrations`) and `style=varied` (`data.demo_style`: demonstrations with human-like
  styles, every task's demonstrator has them); and, sharing round 0, `refit=continue|scratch`
  (`rounds.refit`: each round's fit continues from the previous round's parameters or starts from
  fresh ones; `protocol=`, applied after it, sets it too);
- `protocol=sime`, with any method, the control too: SIME's setup, which the paper's simulation
  experiments follow (`schema.PROTOCOLS`): one observation step, 20-step chunks executed whole,
  `train_0.5` selection, every round re-trained from fresh parameters with round 0's recipe;
  `protocol=continued`: the first campaigns' (2 / 16 / 8 horizons, first success, a continued re-fit);
  where it changes what the presets before it set, `method` gains `-protocol_NAME` and its round 0 is
  its own;
- `head=NAME` (diffusion_unet, flow_unet, mlp);
- `image`: the paper's simulation observations, the agent-view and in-hand cameras' 84 x 84 images
  beside the robot's own low-dim state, without the simulator's object vector (`env.obs_mode`,
  `env.object_vector`), encoded by robomimic's ResNet-18 per camera with random
  76 x 76 crops in training (`policy.encoder`), the images stored unpadded (`data.image_frames`
  frames), SIME's image-task noise scale 0.5; with `cpu` the trunk's widths are 8/16/32/64 (the
  recipe Lift's screen chose: round 0 converged in about 15 minutes of fit here and level with the
  16/32/64/128 trunk fitted to convergence; BENCHMARKS.md, "The image recipe under the picked
  protocol"; accelerators keep ResNet-18's 64/128/256/512) and round 0 fits for the task's steps.
`cpu` and `smoke` also size the `slurm` section, what each job of a campaign on a SLURM cluster asks for
(`cluster`; the paper-scale sizes otherwise). Single fields are overridden on the command line with
`--config.fit.lr=3e-4`.
"""

from __future__ import annotations

import functools

import ml_collections

from soe_jax.envs import registry as env_registry
from soe_jax.experiment import cluster
from soe_jax.experiment.schema import ANY_METHOD_VARIANTS, EXPLORERS, METHODS, PROTOCOLS, VARIANTS
from soe_jax.explore import registry as strategy_registry
from soe_jax.explore import sime
from soe_jax.policies.nets.resnet import CPU_IMAGE_WIDTHS, RESNET18_WIDTHS, SMOKE_IMAGE_WIDTHS
from soe_jax.train import sections as config_sections

PRESETS = ("smoke", "cpu", "head", "image", "expert_data", "protocol") + tuple(VARIANTS) + METHODS + ("quick",)
# The protocol and the demonstrations under `cpu` (docs/protocol.md's rule, applied in RESULTS.md).
CPU_PROTOCOL = "sime"
CPU_STYLE = "varied"
# Under `quick`, `cpu` with fewer states: evaluation start states and exploration start states (of 5 tries each).
QUICK_EVAL_STATES = 100
QUICK_EXPLORE_STATES = 50


def set_fields(c: ml_collections.ConfigDict, fields: dict) -> bool:
  """Set each dotted field of `c` to its value -> whether any changed."""
  changed = False
  for field, value in fields.items():
    *sections, key = field.split(".")
    section = functools.reduce(getattr, sections, c)
    changed |= section[key] != value
    section[key] = value
  return changed


def parse_arg(arg: str | None) -> dict:
  """'smoke,head=mlp' -> {'smoke': True, 'head': 'mlp'}; unknown presets list the known ones."""
  out = {}
  for item in (arg or "").split(","):
    item = item.strip()
    if not item:
      continue
    name, _, value = item.partition("=")
    if name not in PRESETS:
      raise ValueError(f"unknown preset {name!r}; known presets: {', '.join(PRESETS)}")
    out[name] = value if value else True
  return out


def base_config(task: str, num_demos: int) -> ml_collections.ConfigDict:
  """Paper-scale defaults (DESIGN.md): Diffusion Policy's low-dim UNet, the VIB bypass, AdamW 3e-4,
  batch 256, 25k steps, DDIM-10."""
  c = ml_collections.ConfigDict()
  c.seed = 0
  c.method = "soe"
  c.env = ml_collections.ConfigDict(
    dict(
      task=task,
      backend="auto",
      mjx_impl="auto",
      mjx_max_batch=8192,
      mjx_settings="",
      action_mode="absolute",
      episode_length=400,
      obs_mode="low_dim",  # low_dim | image (the cameras' images beside the low-dim vector)
      # Whether the policy reads the simulator's object vector (poses of the objects): a low-dim policy
      # must; an image policy sees the objects in its cameras, as a real robot's does (the paper's).
      object_vector=True,
      image_size=84,
      renderer="auto",  # auto (warp on a CUDA GPU with warp-lang) | gl | warp: what draws the cameras
    )
  )
  # image_frames: the frames of camera images the buffer holds (image policies; their images are stored
  # unpadded, every episode's frames one after another). demo_style: the demonstrator's (scripted, or
  # varied: human-like styles drawn per episode, `experts/`; Lift's so far).
  c.data = ml_collections.ConfigDict(
    dict(num_demos=num_demos, demo_seed=1000, hdf5_path="", filter_key="", max_length=400, capacity=2048,
         image_frames=0, demo_style="scripted")
  )  # fmt: skip
  c.policy = config_sections.policy()
  c.fit = config_sections.fit()
  # Rollouts (evaluation and exploration): environments per compiled slice (0: all), decisions per call.
  c.rollout = ml_collections.ConfigDict(dict(slice_size=0, decisions_per_call=10))
  # Exploration: `tries` rollouts from each of `num_start_states` start states per round, with a
  # strategy by name and its settings (`soe_jax/explore/`; the defaults are the strategy's own).
  c.explore = ml_collections.ConfigDict(dict(strategy=strategy_config("soe"), num_start_states=100, tries=5))
  # Evaluation: the base path from `num_start_states` start states split from `seed`, with the same
  # policy-sampling keys in every round and for every method of a training seed (paired outcomes).
  c.eval = ml_collections.ConfigDict(dict(num_start_states=200, seed=77_777))
  # Rounds after round 0: select episodes (first_success | shortest_success | all_successes | sime;
  # length_cap > 0: only successes no longer than length_cap x the demonstrations' mean length), append, re-fit
  # (continue from the previous round's parameters for refit_steps at a peak lr of refit_lr, 0 meaning
  # fit.lr; or scratch), evaluate.
  # refit_ema: a continued re-fit's EMA restarts from the parameters (restart) or goes on (carry).
  # steered: which episodes saved from the steering page the next fit takes (successful | all).
  # new_data: what a round adds to the data: the episodes exploration kept (kept), the scripted
  # demonstrator's episodes from the start states of those (expert: an oracle), or nothing (none: the
  # control, which explores not at all).
  # round0_dir: where the shared round 0 lives ("" = <workdir>/../round0).
  # demo_fraction: > 0, each re-fit batch draws that share from the demonstrations and the rest from the
  # other episodes (0: uniformly over every window). aligned_windows: self-collected episodes' windows
  # start at recorded decisions only, so no window's executed part splices two sampled chunks.
  # Logging beside metrics.jsonl and TensorBoard (never part of the experiment: a run resumes with other
  # settings here): wandb mirrors each phase's numbers, with the config and the commit, to the project
  # `wandb_project` (WANDB_MODE=offline keeps it on disk, in <workdir>/wandb). videos: each evaluation and
  # exploration stores its first `videos` episodes, drawn to MP4 in <workdir>/videos/ (0: none).
  c.log = ml_collections.ConfigDict(dict(wandb=False, wandb_project="soe_jax", videos=4))
  # What each job of a campaign on SLURM asks for (partition, time_min, cpus, gpus, mem_gb; `cluster`):
  # never part of the experiment either.
  c.slurm = cluster.section()
  c.rounds = ml_collections.ConfigDict(
    dict(num_rounds=3, select="first_success", length_cap=0.0, refit="continue", refit_steps=10_000, refit_lr=0.0,
         refit_ema="restart", steered="successful", new_data="kept", round0_dir="", demo_fraction=0.0,
         aligned_windows=False)
  )  # fmt: skip
  return c


def strategy_config(name: str) -> ml_collections.ConfigDict:
  """`explore.strategy` for strategy `name`: its name and all its settings at their defaults."""
  return ml_collections.ConfigDict(dict(name=name, kwargs=strategy_registry.default_settings(name)))


def apply_presets(
  c: ml_collections.ConfigDict,
  arg: str | None,
  cpu_demos: int | None = None,
  cpu_steps: int = 10_000,
  cpu_image_demos: int | None = None,
  cpu_image_steps: int = 4_000,
  smoke_episode_length: int | None = 24,
  quick_steps: int | None = None,
) -> ml_collections.ConfigDict:
  """`cpu_demos`, `cpu_steps`: the task's number of demonstrations and round-0 fit steps under the `cpu`
  preset: a task may need another number of demonstrations than the paper's for its converged base
  policy to succeed on the 20-80% of start states the experiment wants, or a longer fit to converge.
  `cpu_image_demos` (default `cpu_demos`), `cpu_image_steps`: the same under `cpu,image`.
  `smoke_episode_length`: the episodes' length under `smoke` (None: the task's own, for a demonstrator
  that needs it to succeed at all; varied demonstrations, as under `cpu`, always have the task's own).
  `quick_steps`: every fit's steps under `quick` (None: the task has no `quick` run)."""
  presets = parse_arg(arg)
  if presets.get("quick"):  # `cpu`, shorter: see below
    if quick_steps is None:
      raise ValueError(f"quick: no quick run is calibrated for {c.env.task}; configs/lift.py:quick is")
    if presets.get("image"):
      raise ValueError("quick is a low-dimensional run; it takes no image preset")
    presets["cpu"] = True
  methods = [m for m in METHODS if presets.get(m)]
  if len(methods) > 1:
    raise ValueError(f"choose one method preset, got {', '.join(methods)}")
  if methods:
    c.method = methods[0]
    c.explore.strategy = strategy_config("dp" if methods[0] == "control" else methods[0])
  if methods == ["control"]:
    c.rounds.new_data = "none"  # (its explore.strategy is never used)
  explorer = c.method in EXPLORERS
  if presets.get("expert_data"):
    if not explorer:
      raise ValueError(f"expert_data goes with an exploring method ({', '.join(EXPLORERS)}), e.g. 'soe,expert_data'")
    c.method = f"{c.method}-expert_data"
    c.rounds.new_data = "expert"
  steer = c.explore.strategy.kwargs if c.explore.strategy.name == "soe_steer" else None
  if presets.get("cpu"):  # (before the variants, which may set the fields it sets)
    # The recipe that converged fastest on a 2-core CPU (BENCHMARKS.md, "Convergence of round 0"): the
    # narrow UNet 32/64/128, AdamW 1e-3 at batch 64; re-fits continue at 3e-4 with the EMA carried on.
    # (The IB path's head loss on a quarter of each batch fits 20% faster but explores worse.)
    config_sections.cpu_recipe(c)
    c.fit.num_steps = cpu_steps
    c.data.num_demos = cpu_demos or c.data.num_demos
    c.rounds.update(num_rounds=1, refit_steps=3000, refit_lr=3e-4, refit_ema="carry")
    config_sections.adopted_refit(c)  # (a robot's `cpu` preset takes the same)
    # The oracle arms' scripted episodes were never sampled in chunks: every window of theirs is drawn.
    c.rounds.aligned_windows = c.rounds.new_data != "expert"
    set_fields(c, PROTOCOLS[CPU_PROTOCOL])
    c.data.demo_style = CPU_STYLE
    if steer is not None:  # a whole round of 500 steered episodes: lighter steering
      steer.update(num_proposals=8, every=4, max_dims=2)
    c.slurm.update(cluster.CPU)
  if presets.get("quick"):  # about ten minutes on 2 cores: shorter fits, fewer evaluation and exploration states
    c.fit.num_steps = quick_steps
    c.eval.num_start_states = QUICK_EVAL_STATES
    c.explore.num_start_states = QUICK_EXPLORE_STATES
  for preset, (field, suffix) in VARIANTS.items():
    if preset not in presets:
      continue
    value = presets[preset]
    if value is True:
      raise ValueError(f"the preset {preset} needs a value: {preset}=VALUE")
    if not explorer and preset not in ANY_METHOD_VARIANTS:
      raise ValueError(f"{preset}= goes with an exploring method ({', '.join(EXPLORERS)}), e.g. 'soe,{preset}={value}'")
    *sections, name = field.split(".")
    section = functools.reduce(getattr, sections, c)
    if name not in section:
      raise ValueError(f"{preset}: strategy {c.explore.strategy.name!r} has no setting {name!r}")
    # The arm's name gains the variant only where it changes the field (from the presets before it).
    before = section[name]
    if isinstance(before, bool):  # (bool("false") is True): `aligned` names itself, `aligned=false` `aligned_false`
      if value.lower() not in ("true", "false"):
        raise ValueError(f"{preset}={value}: expected true or false")
      section[name] = value.lower() == "true"
      tag = suffix if section[name] else f"{suffix}_false"
    else:
      try:
        section[name] = type(before)(value)
      except ValueError:
        raise ValueError(f"{preset}={value}: expected a {type(before).__name__}, e.g. {preset}={before}") from None
      tag = f"{suffix}{value}"
    if section[name] != before:
      c.method = f"{c.method}-{tag}"
  if presets.get("smoke"):
    config_sections.smoke_recipe(c)
    c.data.num_demos = min(c.data.num_demos, 4)
    c.data.capacity = 64
    # (Varied demonstrations keep the task's horizon: their styles' slower paces need 40-80 steps on Lift.)
    if c.data.demo_style != "varied":
      c.env.episode_length = smoke_episode_length or c.env.episode_length
    c.explore.update(num_start_states=3, tries=2)
    if steer is not None:
      steer.update(num_proposals=4, num_choices=2, max_dims=2, snr_windows=64)
    c.eval.num_start_states = 4
    c.rounds.update(num_rounds=2, refit_steps=20)
    c.log.videos = 0  # (the tests that watch episodes ask for them)
    c.slurm.update(cluster.SMOKE)
  if presets.get("image"):
    widths = SMOKE_IMAGE_WIDTHS if presets.get("smoke") else CPU_IMAGE_WIDTHS if presets.get("cpu") else RESNET18_WIDTHS
    c.env.obs_mode = "image"
    c.env.object_vector = False  # the paper's: images and proprioception
    cameras = env_registry.image_keys(c.env.task)
    c.policy.encoder = ml_collections.ConfigDict(
      dict(name="image", kwargs=dict(cameras=cameras, crop_size=76, widths=widths, shared=False))
    )
    # Two 84 x 84 cameras: 42 kB a frame (4.2 GB for 100k frames; 1.7 GB for the CPU's 40k); Transport's
    # four, twice that.
    c.data.image_frames = 2_000 if presets.get("smoke") else 40_000 if presets.get("cpu") else 100_000
    if presets.get("cpu") and not presets.get("smoke"):
      # A round-0 fit within about 15 minutes here (the whole step 118 ms at one frame: BENCHMARKS.md).
      c.fit.num_steps = cpu_image_steps
      c.data.num_demos = cpu_image_demos or c.data.num_demos
    if c.explore.strategy.name == "sime":
      c.explore.strategy.kwargs.scale = sime.IMAGE_SCALE
  if "head" in presets:
    name = presets["head"]
    c.policy.head.name = name
    if name == "mlp":  # the UNet's settings do not apply to the regression head
      c.policy.head.kwargs = ml_collections.ConfigDict(dict(hidden=(1024, 1024)))
    elif name == "flow_unet":  # Euler steps instead of a DDPM/DDIM sampler
      kwargs = c.policy.head.kwargs.to_dict()
      kwargs.pop("sampler")
      c.policy.head.kwargs = ml_collections.ConfigDict(kwargs)
  if "protocol" in presets:
    name = presets["protocol"]
    if name not in PROTOCOLS:
      raise ValueError(f"unknown protocol {name!r}; known protocols: {', '.join(PROTOCOLS)}")
    if set_fields(c, PROTOCOLS[name]):  # (as a variant: the arm is named by what its presets change)
      c.method = f"{c.method}-protocol_{name}"
  return c

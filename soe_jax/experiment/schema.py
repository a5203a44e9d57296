"""The config's knowledge in one place: which fields form which group (what round 0 depends on, what an
arm of the experiment is, what only logs), the values a field may take, and the history of fields added
or renamed since configs were first saved. Other modules import these; nothing here imports MuJoCo or
JAX. The fields themselves and their defaults are `presets.base_config`.
"""

from __future__ import annotations

# How a run is logged and watched (wandb, videos): never part of the experiment, and a run resumes with
# other values here.
LOGGING = "log."
# What a campaign's jobs ask of a SLURM cluster (`cluster`): never part of the experiment either.
CLUSTER = "slurm."
# Fields that are no setting of an experiment: its training seed and where its shared round 0 lives.
NOT_SETTINGS = ("seed", "rounds.round0_dir")


def is_setting(key: str) -> bool:
  """Whether the flattened field `key` is a setting of the experiment: not its seed, where its round 0
  lives, how it is logged or what its cluster jobs ask for."""
  return key not in NOT_SETTINGS and not key.startswith((LOGGING, CLUSTER))


# What a method's run and its control may differ in: the arm itself (how it explores, what it keeps).
# (The action range and frame change round 0 too; their arms pair with the control of the default range
# and frame. The demonstrations' style, the protocol and the re-fit are not here: their arms pair with a
# control fitted on the same demonstrations under the same protocol and re-fit.)
ARM = ("method", "explore.", "rounds.new_data", "rounds.select", "rounds.length_cap", "policy.action_range",
       "rounds.demo_fraction", "rounds.aligned_windows", "policy.bypass.beta", "policy.action_frame")  # fmt: skip
# Arm fields that refit round 0 but leave its base path as it is (the bypass's loss never reaches the
# encoder or the head): an arm differing from its control there pairs with it only where their round-0
# evaluations agree state by state.
SAME_BASE_PATH = ("policy.bypass.beta",)

# Sections that do not change round 0 (so methods differing only there share it), and fields that
# change neither its parameters nor its numbers (the fit's in-fit evaluations).
NOT_ROUND0 = ("method", "explore", "rounds", LOGGING.rstrip("."), CLUSTER.rstrip("."))
NOT_ROUND0_FIELDS = ("fit.eval_every", "fit.eval_states", "env.mjx_max_batch")
# Fields added since configs were first saved, with the value that does what a config without them
# did: a saved config lacking one reads as having that value.
ADDED = {
  "rounds.steered": "successful",
  "rounds.refit_ema": "restart",
  "fit.eval_every": 0,
  "fit.eval_states": 50,
  "policy.bypass.batch_fraction": 1.0,
  "rounds.new_data": "kept",
  "rounds.length_cap": 0.0,
  "data.filter_key": "",
  "log.wandb": False,
  "log.wandb_project": "soe_jax",
  "env.mjx_impl": "auto",
  "env.mjx_max_batch": 8192,
  "env.renderer": "auto",
  "env.mjx_settings": "",
  "log.videos": 0,
  "env.obs_mode": "low_dim",
  "env.image_size": 84,
  "data.image_frames": 0,
  "policy.action_range": "demonstrations",
  "policy.action_frame": "absolute",
  "rounds.demo_fraction": 0.0,
  "rounds.aligned_windows": False,
  "env.object_vector": True,
  "data.demo_style": "scripted",
  "slurm.partition": "",
  "slurm.time_min": 1440,
  "slurm.cpus": 8,
  "slurm.gpus": 1,
  "slurm.mem_gb": 32.0,
}
# Fields a run may resume with other values in: how it is logged and watched, what its cluster jobs ask
# for, and MJX's batch cap.
NOT_COMPARED = (LOGGING, CLUSTER, "env.mjx_max_batch")
# Strategy settings added since, likewise: strategy -> {setting: the value that does what its absence did}.
ADDED_SETTINGS = {"soe": {"hold": 1}}
# Fields of configs saved before they moved: old name -> new name ("a.b." is a whole section).
RENAMED = {
  "env.horizon": "env.episode_length",
  "explore.method": "method",
  "explore.strategy": "explore.strategy.name",
  "explore.alpha": "explore.strategy.kwargs.alpha",
  "explore.sime.": "explore.strategy.kwargs (sime's scale, tau1, tau2)",
  "explore.steer.": "explore.strategy.kwargs (soe_steer's settings)",
  "explore.slice_size": "rollout.slice_size",
  "explore.decisions_per_call": "rollout.decisions_per_call",
}

# The values some fields may take.
REFITS = ("continue", "scratch")
REFIT_EMA = ("restart", "carry")  # a continued re-fit's EMA
STEERED = ("successful", "all")  # which steered episodes a fit takes
NEW_DATA = ("kept", "expert", "none")  # what a round adds to the data
ACTION_RANGES = ("workspace", "demonstrations")  # what action positions are normalised over
# Fields that count something: at least 1.
POSITIVE = ("env.episode_length", "env.mjx_max_batch", "data.num_demos", "data.capacity", "data.max_length", "policy.n_obs_steps",
            "policy.horizon", "policy.n_action_steps", "fit.num_steps", "fit.batch_size", "fit.chunk_size",
            "fit.eval_states", "rollout.decisions_per_call", "explore.num_start_states", "explore.tries",
            "eval.num_start_states", "rounds.refit_steps", "slurm.time_min", "slurm.cpus")  # fmt: skip
NON_NEGATIVE = (
  "rollout.slice_size",
  "rounds.num_rounds",
  "fit.warmup_steps",
  "fit.checkpoint_every",
  "log.videos",
  "data.image_frames",
  "fit.eval_every",
  "rounds.refit_lr",
  "rounds.length_cap",
  "slurm.gpus",
  "slurm.mem_gb",
)

# A method is an arm of the experiment; each explorer explores with the strategy of the same name, and
# the control re-fits without new data.
EXPLORERS = ("dp", "sime", "soe", "soe_steer")
METHODS = EXPLORERS + ("control",)
# Presets that change what an exploring method keeps or how it explores: preset -> (field, method suffix).
VARIANTS = {
  "select": ("rounds.select", "select_"),
  "length_cap": ("rounds.length_cap", "cap"),
  "alpha": ("explore.strategy.kwargs.alpha", "alpha"),
  "hold": ("explore.strategy.kwargs.hold", "hold"),
  "beta": ("policy.bypass.beta", "beta"),  # the KL ablation (round 0 too: its own, as the bypass trains there)
  "demo_fraction": ("rounds.demo_fraction", "demos"),  # the re-fit's share of demonstration windows
  "aligned": ("rounds.aligned_windows", "aligned"),  # re-fit windows at decisions only
  "range": ("policy.action_range", "range_"),  # (round 0 too; any method, the control too)
  "frame": ("policy.action_frame", "frame_"),  # (round 0 too; any method, the control too)
  "style": ("data.demo_style", "style_"),  # the demonstrator's (round 0 too; any method, the control too)
  "refit": ("rounds.refit", "refit_"),  # from fresh parameters or continued (any method, the control too)
}
# Variants that go with any method, the control too (the others change how a method explores).
ANY_METHOD_VARIANTS = ("range", "frame", "style", "refit")
# Experiment protocols (`protocol=NAME`, any method, the control too): name -> the fields it sets, over
# every other preset's. `sime`: SIME's setup (specs/sime_baseline.md), which the paper's simulation
# experiments follow: one observation step, a 20-step chunk executed whole, `train_0.5` selection, and
# every round re-trained from freshly initialised parameters with round 0's recipe. `continued`: the
# protocol this project's first campaigns ran (RESULTS.md): Diffusion Policy's 2 / 16 / 8 horizons, each
# state's first success kept, and each round's re-fit continuing from the previous round's parameters.
PROTOCOLS = {
  "sime": {
    "policy.n_obs_steps": 1,
    "policy.horizon": 20,
    "policy.n_action_steps": 20,
    "rounds.select": "sime",
    "rounds.refit": "scratch",
  },
  "continued": {
    "policy.n_obs_steps": 2,
    "policy.horizon": 16,
    "policy.n_action_steps": 8,
    "rounds.select": "first_success",
    "rounds.refit": "continue",
  },
}

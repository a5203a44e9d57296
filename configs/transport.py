"""Transport: the self-improvement experiment on robomimic's TwoArmTransport (two arms hand the
hammer over into the target bin while the trash goes to the trash bin).

  python -m soe_jax run --config=configs/transport.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (soe_jax/experiment/presets.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/transport-soe-seed0/. Swap `soe`
for `dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Episodes run to robomimic's 700-step horizon (the scripted demonstrations take 417 steps on average);
actions are 20 numbers (robot0's 10, then robot1's) and observations 59.

Demonstrations: 20, as for Can and Square. The `cpu` preset fits round 0 for 20k steps with a UNet
twice as wide as the other tasks' (64/128/256): the narrow one's 32-channel first level does not carry
20 action channels (1,500 steps on the 20 demonstrations: loss 0.87 and the gripper channels'
noise unpredicted, against 0.076 at 64/128/256; the same narrow net on Square's 10-d actions reaches
0.088, on Square's actions repeated to 20 channels 0.93). Its round 0 (seed 0, 30 min on 2 cores)
succeeds on 82.5% of 200 evaluation states (results/latent-dims/transport_d16_seed0.json). Every preset keeps the 700-step horizon
(`smoke` too: the demonstrator needs ~300 steps to reach the handover).
"""

from soe_jax.experiment import presets

HORIZON = 700  # robomimic's evaluation horizon for transport


def get_config(arg=None):
  c = presets.base_config("transport", num_demos=20)
  c.env.episode_length = HORIZON
  c.data.max_length = HORIZON
  # `smoke` keeps the whole horizon: the demonstrator needs 350 to 420 steps (the handover).
  c = presets.apply_presets(c, arg, cpu_steps=20_000, smoke_episode_length=None)
  if presets.parse_arg(arg).get("cpu") and not presets.parse_arg(arg).get("smoke"):
    c.policy.head.kwargs.down_dims = (64, 128, 256)
  return c

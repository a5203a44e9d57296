"""Simulated manipulation tasks on MuJoCo (MJX or the C engine) behind brax's `Env` interface."""

from soe_jax.envs.manipulation import POLICY_OBS_KEYS, ManipulationEnv, policy_obs
from soe_jax.envs.registry import env_names, make_env, register_env
from soe_jax.envs.wrappers import wrap_env

__all__ = ["POLICY_OBS_KEYS", "ManipulationEnv", "policy_obs", "env_names", "make_env", "register_env", "wrap_env"]

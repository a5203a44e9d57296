"""soe_jax: on-manifold exploration (SOE) for robot policy self-improvement, in JAX."""

__version__ = "0.1.0"

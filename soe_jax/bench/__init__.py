"""Benchmarks: `python -m soe_jax.bench <what> ...`, each printing one JSON object last."""

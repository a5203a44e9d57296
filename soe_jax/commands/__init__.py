"""Every entry point, thin: flags -> one library call (`python -m soe_jax COMMAND`)."""

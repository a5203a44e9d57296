"""Flax (Linen) networks."""

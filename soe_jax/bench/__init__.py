"""Benchmarks (`python -m soe_jax bench SUB ...`), each returning one JSON-ready record."""

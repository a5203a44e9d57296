"""Scripted demonstrators (pure JAX, vmappable) standing in for robomimic's proficient-human data."""

"""Exploration: strategies and steering."""

"""Policies: networks, the diffusion schedule and samplers, heads, the VIB bypass and the dual-path policy."""

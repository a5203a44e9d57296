"""Fitting a policy: compiled chunks of SGD steps, the train state, checkpoints."""

"""A robot of one's own: a policy fitted and re-fitted on dataset files alone (no simulator, no task registry)."""

"""The run: rounds of explore, keep, re-fit and evaluate, their phases, run directory, config schema and presets, validation, selection, run log and videos."""

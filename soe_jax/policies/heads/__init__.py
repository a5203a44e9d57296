"""Action heads: pure (init, loss, sample) functions over a conditioning vector."""

"""Process plumbing every command shares: one-line errors, interrupts, the compilation cache, accelerators, sharding, provenance, config files, atomic JSON."""

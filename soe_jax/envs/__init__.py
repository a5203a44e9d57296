"""Simulated manipulation tasks on MuJoCo (MJX or the C engine) behind brax's `Env` interface: by name
in `registry` (`make_env`), the observation layout in `observations`, the shared task in `manipulation`.
Importing the package imports nothing, so code that uses only the MuJoCo-free modules (`observations`,
`registry`, `controller`, `backends`) does not load MuJoCo and brax."""

"""Episode storage: robomimic's HDF5 layout."""

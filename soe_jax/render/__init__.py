"""Camera images of a scene, drawn by processes of their own (`pool.Renderer`; `child` is the process)."""

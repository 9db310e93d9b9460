"""Shared core: robot models, objects and meshes, signed distance fields, collision checking, files,
timed trajectories (joint velocity and acceleration limits)."""

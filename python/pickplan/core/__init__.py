"""Shared core: robot models, objects and meshes, signed distance fields, collision checking, files."""

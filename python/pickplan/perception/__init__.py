"""Perception: a world model for the planner from depth cameras (no meshes, no stored grasps)."""

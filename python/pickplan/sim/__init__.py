"""Simulation in PyBullet: seeded cluttered scenes, execution of plans (follow, close, lift), rendering."""

"""Trajectory optimization (impact-aware DDP, HS-DDP, STO) and the policies built on it."""

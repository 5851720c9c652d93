"""Gymnasium environments for the planar Mini Cheetah."""

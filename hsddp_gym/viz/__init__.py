"""Figures and frames: matplotlib plots of plans and learning curves, rendering of states and GIFs."""

"""hsddp_gym: HS-DDP for the planar MIT Mini Cheetah, and a Gymnasium bounding benchmark."""

__version__ = "0.1.0"

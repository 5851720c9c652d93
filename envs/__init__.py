"""Gymnasium environments for the planar Mini Cheetah.

* :mod:`envs.contact`: the state-based contact simulator (time-stepping, exact planar Coulomb LCP).
* :mod:`envs.bounding`: ``BoundingEnv``, registered as ``hsddp_gym/Bounding-v0`` by ``import hsddp_gym``.

Classes are imported lazily so that ``import envs`` stays cheap.
"""

__all__ = ["BoundingEnv", "ContactSimulator"]


def __getattr__(name):
    if name == "BoundingEnv":
        from envs.bounding import BoundingEnv

        return BoundingEnv
    if name == "ContactSimulator":
        from envs.contact import ContactSimulator

        return ContactSimulator
    raise AttributeError(f"module 'envs' has no attribute {name!r}")

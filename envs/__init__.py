"""Installed as ``hsddp_gym.envs``: Gymnasium environments for the planar Mini Cheetah.

* [`hsddp_gym.core.contact`][hsddp_gym.core.contact]: the state-based contact simulator (time-stepping; its exact planar
Coulomb LCP in [`hsddp_gym.core.contact_lcp`][hsddp_gym.core.contact_lcp]).
* [`hsddp_gym.envs.bounding`][hsddp_gym.envs.bounding]: ``BoundingEnv``, registered as ``hsddp_gym/Bounding-v0`` by
``import hsddp_gym``.
* [`hsddp_gym.envs.vector`][hsddp_gym.envs.vector]: ``BoundingVectorEnv``, N robots in one compiled call, the
``vector_entry_point`` of ``hsddp_gym/Bounding-v0`` (``gym.make_vec``).
* [`hsddp_gym.envs.pronking`][hsddp_gym.envs.pronking]: ``PronkingEnv``, the pronking task on the same robot, registered
as ``hsddp_gym/Pronking-v0`` (``MuJoCoPronkingEnv``: ``hsddp_gym/PronkingMuJoCo-v0``).
* [`hsddp_gym.envs.backflip`][hsddp_gym.envs.backflip]: ``BackflipEnv``, the backflip task on the same robot, registered
as ``hsddp_gym/Backflip-v0`` (``MuJoCoBackflipEnv``: ``hsddp_gym/BackflipMuJoCo-v0``).
* [`hsddp_gym.envs.jumps`][hsddp_gym.envs.jumps]: ``JumpEnv``, a jump over a gap or onto a box from a bound, registered
as ``hsddp_gym/GapJump-v0`` and ``hsddp_gym/BoxJump-v0`` (``MuJoCoJumpEnv``: ``hsddp_gym/GapJumpMuJoCo-v0``,
  ``hsddp_gym/BoxJumpMuJoCo-v0``).
* [`mujoco_twin`][hsddp_gym.envs.mujoco_twin]: ``MuJoCoBoundingEnv``, the same task on MuJoCo, registered as
  ``hsddp_gym/BoundingMuJoCo-v0`` (optional extra ``mujoco``).

Classes are imported lazily so that ``import hsddp_gym.envs`` stays cheap.
"""

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {"backflip": ("BackflipEnv", "MuJoCoBackflipEnv"), "bounding": ("BoundingEnv",),
            "contact": ("ContactSimulator",), "jumps": ("JumpEnv", "MuJoCoJumpEnv"),
            "mujoco_twin": ("MuJoCoBoundingEnv",),
            "pronking": ("MuJoCoPronkingEnv", "PronkingEnv"),
            "vector": ("BoundingVectorEnv",)}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = ["BackflipEnv", "BoundingEnv", "BoundingVectorEnv", "ContactSimulator", "JumpEnv", "MuJoCoBackflipEnv",
           "MuJoCoBoundingEnv", "MuJoCoJumpEnv", "MuJoCoPronkingEnv", "PronkingEnv"]

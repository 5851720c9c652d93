"""The ground the MPC plans on: the episode's terrain, when it is given, and where the feet put the ground.

Without a terrain the MPC plans for the plane ``z = 0`` of the measurement's frame, raised or lowered to where the
feet on the ground put it (the state estimator's calibrated height bias, or the schedule estimator's search for the
ground before that calibration). Given the terrain (privileged information: ``MPCPolicy(..., terrain=...)``) the
MPC works in the world frame: the plans' switching constraints put a landing foot on the terrain under it, the
reference heights follow the ground under the trunk, and the late-landing rule, the state filter, the bias estimate
and the flight reach measure the feet from the terrain.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import IZ
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.core.terrain import Terrain, check_terrain


def env_terrain(env):
    """A function of no argument returning the terrain of ``env``'s current episode (its unwrapped env's ``terrain``
    attribute: a [`Terrain`][hsddp_gym.core.terrain.Terrain], or None on flat ground), for
    ``MPCPolicy(..., terrain=env_terrain(env))``: a random terrain (``hsddp_gym/Terrain-v0``) is drawn at every reset
    of the env, and the MPC reads it at its own reset."""
    unwrapped = env.unwrapped

    def terrain():
        return getattr(unwrapped, "terrain", None)

    return terrain


def check_terrain_source(terrain):
    """``terrain`` as given to the MPC: None, a Terrain or a function returning the episode's; else TypeError."""
    if terrain is not None and not isinstance(terrain, Terrain) and not callable(terrain):
        raise TypeError(f"terrain must be None, a Terrain or a function returning the episode's Terrain "
                        f"(e.g. env_terrain(env)), got {type(terrain).__name__}")
    return terrain


class GroundModel:
    """The episode's terrain (None: flat ground) and the heights the plans read from it.

    Args:
        source: None, a [`Terrain`][hsddp_gym.core.terrain.Terrain], or a function of no argument returning the
            current episode's (read at every [`reset`][reset], see [`env_terrain`][env_terrain]).
        hip_offset: the hips' distance from the trunk's centre along the trunk [m].
    """

    def __init__(self, source, hip_offset: float) -> None:
        self.source = check_terrain_source(source)
        self.hip_offset = float(hip_offset)
        self.terrain: Terrain | None = None

    def reset(self) -> Terrain | None:
        """Read the episode's terrain (a flat one is None); returns it."""
        source = self.source
        if source is None:
            return self.terrain
        name = "terrain"
        if not isinstance(source, Terrain):
            source, name = source(), "terrain()"
        terrain = check_terrain(source, name)
        self.terrain = None if terrain is None or terrain.is_flat else terrain
        return self.terrain

    def under_trunk(self, xs) -> np.ndarray:
        """The ground [m] under the trunk x ``xs`` (any shape) [m]: the mean of the terrain under its two hips (the
        trunk level), 0 without a terrain."""
        xs = np.asarray(xs, dtype=np.float64)
        if self.terrain is None:
            return np.zeros_like(xs)
        return 0.5 * (self.terrain.support_heights(xs - self.hip_offset)
                      + self.terrain.support_heights(xs + self.hip_offset))

    def level(self, x: np.ndarray) -> np.ndarray:
        """``x`` (14,) with its height measured from [`under_trunk`][under_trunk] (``x`` itself without a terrain): for
        the heuristic controllers, which hold a trunk height above flat ground."""
        if self.terrain is None:
            return x
        x = np.array(x, dtype=np.float64)
        x[IZ] -= float(self.under_trunk(x[0]))
        return x

    def for_plan(self, schedule: ModeSchedule, x: float, speed: float, height: float
                 ) -> tuple[np.ndarray | None, Terrain | None]:
        """The ground of a plan of ``schedule`` from trunk x ``x`` [m] at ``speed`` [m/s] with the ground ``height``
        [m] above the terrain (where the feet put it): ``(ground, terrain)``, both None on the flat ground ``z = 0``.
        Else ``ground (n,)`` [m], each phase's reference trunk heights raised by the ground under the trunk where it is
        expected at the phase's end plus ``height``, and ``terrain`` the ground of the switching constraints (a landing
        foot's height above it): the terrain (None: flat) raised by ``height``."""
        if self.terrain is None and height == 0.0:
            return None, None
        ends = x + speed * np.cumsum(schedule.durations)
        terrain = self.terrain
        if height != 0.0:
            terrain = (Terrain.flat() if terrain is None else terrain).raised(height)
        return self.under_trunk(ends) + height, terrain

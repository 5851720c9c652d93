"""Physical parameters of the planar MIT Mini Cheetah, with the source of every number.

Sources: "code" = the authors' public MATLAB code as summarized in
``shared/reference/original_code_facts.md`` (section numbers given); "paper" = Li & Wensing, RA-L 2020.
The 2D model lumps the four ab/ad links into the trunk and doubles each leg (left + right), so one 2D
leg and one 2D joint torque stand for a pair of real legs / motors.
"""

from __future__ import annotations

import dataclasses
import math


@dataclasses.dataclass(frozen=True)
class LinkParams:
    """One rigid link of the planar model (only mass, (x, z) CoM and I_yy act in the plane).

    Attributes:
        mass: [kg].
        com_z: CoM offset along the link's own -z direction is ``com_z`` (negative = below the joint) [m].
        inertia_yy: rotational inertia about the CoM around +y [kg m^2].
        length: distance from this link's joint to the next joint / foot along -z [m].
    """

    mass: float
    com_z: float
    inertia_yy: float
    length: float = 0.0

    def __post_init__(self) -> None:
        for name in ("mass", "inertia_yy"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"LinkParams.{name} must be a positive finite number, got {value!r}")
        if not (math.isfinite(self.length) and self.length >= 0.0):
            raise ValueError(f"LinkParams.length must be finite and >= 0, got {self.length!r}")


@dataclasses.dataclass(frozen=True)
class RobotParams:
    """The planar Mini Cheetah (code §1.2, ``get2DMCParams.m``), point feet, ground at z = 0.

    Defaults:
        trunk: 5.46 kg (3.3 body + 4 x 0.54 ab/ad), I_yy = 0.036203 + 4(0.00056 + 0.54 * 0.19^2)
            = 0.116419 kg m^2, CoM at the trunk origin (code §1.2).
        thigh: 2 x 0.634 = 1.268 kg, CoM 0.02 m below the hip, I_yy 4.206e-3, length 0.209 m (code §1.2).
        shank: 2 x 0.064 = 0.128 kg, CoM 0.061 m below the knee, I_yy 4.96e-4, length 0.195 m (code §1.2).
        hip_offset: hips at +-0.19 m along the trunk x axis (code §1.2).
        gravity: 9.81 m/s^2 (code §1.1).
        torque_limit: |u_j| <= 33 N m per 2D joint, i.e. 2 x 16.5 N m motors (code §2; paper eq. 17e).
        friction: mu = 0.6 (code §2; paper eq. 17g).
    Rotor inertia and gear ratios are not modelled, as in all of the authors' 2D code (code §1.2).
    """

    trunk: LinkParams = LinkParams(mass=5.46, com_z=0.0, inertia_yy=0.116419)
    thigh: LinkParams = LinkParams(mass=1.268, com_z=-0.02, inertia_yy=4.206e-3, length=0.209)
    shank: LinkParams = LinkParams(mass=0.128, com_z=-0.061, inertia_yy=4.96e-4, length=0.195)
    hip_offset: float = 0.19
    gravity: float = 9.81
    torque_limit: float = 33.0
    friction: float = 0.6

    def __post_init__(self) -> None:
        for name in ("hip_offset", "gravity", "torque_limit", "friction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"RobotParams.{name} must be a positive finite number, got {value!r}")
        for name in ("trunk", "thigh", "shank"):
            if not isinstance(getattr(self, name), LinkParams):
                raise TypeError(f"RobotParams.{name} must be a LinkParams, got {type(getattr(self, name))}")

    @property
    def total_mass(self) -> float:
        """Trunk + 2 thighs + 2 shanks [kg] (8.252 kg by default)."""
        return self.trunk.mass + 2.0 * (self.thigh.mass + self.shank.mass)

    def with_trunk_mass_scale(self, scale: float) -> RobotParams:
        """These parameters with the trunk's mass and pitch inertia times ``scale`` (> 0; a payload at the trunk's
        centre of mass): a new ``RobotParams`` (``self`` for 1)."""
        if not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(f"scale must be a positive finite number, got {scale!r}")
        if scale == 1.0:
            return self
        trunk = dataclasses.replace(self.trunk, mass=self.trunk.mass * scale, inertia_yy=self.trunk.inertia_yy * scale)
        return dataclasses.replace(self, trunk=trunk)

    @property
    def leg_length(self) -> float:
        """Thigh + shank length [m] (0.404 m): hip height with straight legs standing on the ground."""
        return self.thigh.length + self.shank.length


DEFAULT_PARAMS = RobotParams()

"""The one place that defines state order, contact modes, feet, signs and units.

Everything else in the project imports these names; nothing re-derives them.

Coordinates (SI units, radians)
-------------------------------
World frame: +x forward, +z up, +y into the page; every rotation is about +y.
The ground is the plane ``z = 0``.

Generalized coordinates ``q`` (7,)::

    q = [x, z, pitch, hip_front, knee_front, hip_back, knee_back]

* ``x, z``: trunk origin (midpoint between the hips) in the world frame.
* ``pitch``: trunk rotation about +y. **Positive pitch is nose-down** (the front hip drops).
* ``hip_*``: thigh angle relative to the trunk. **Positive swings the thigh backward** (the foot moves
  toward -x). Zero configuration: legs straight down, body level.
* ``knee_*``: shank angle relative to the thigh, same sign rule. Bounding postures have hips near
  +0.25*pi..+0.35*pi and knees near -0.5*pi..-0.75*pi (knees pointing backward).

Generalized velocities ``v = dq/dt`` (7,), same order. State ``x = [q, v]`` (14,).
Controls ``u`` (4,) are joint torques [N m] in the joint order ``[hip_front, knee_front, hip_back,
knee_back]``; a positive torque accelerates its joint angle positively.

Feet and contact modes
----------------------
Feet are indexed ``FRONT = 0``, ``BACK = 1``. A contact mode is a bit mask of the feet on the ground:
``FLIGHT = 0``, ``FRONT_STANCE = 1``, ``BACK_STANCE = 2``, ``DOUBLE_STANCE = 3``.

Ground reaction forces ``grf`` (4,) = ``[f_front_x, f_front_z, f_back_x, f_back_z]`` [N] are the forces
the ground applies **on the robot** (``f_z > 0`` pushes up); entries of feet not in contact are zero.
"""

from __future__ import annotations

import enum

import numpy as np

NQ = 7
"""Number of generalized coordinates."""
NV = 7
"""Number of generalized velocities."""
NX = NQ + NV
"""State dimension, ``x = [q, v]``."""
NU = 4
"""Control dimension (joint torques)."""
NGRF = 4
"""Size of the ground-reaction-force vector ``[f_front_x, f_front_z, f_back_x, f_back_z]``."""

Q_NAMES = ("x", "z", "pitch", "hip_front", "knee_front", "hip_back", "knee_back")
X_NAMES = Q_NAMES + tuple("d" + n for n in Q_NAMES)
U_NAMES = ("tau_hip_front", "tau_knee_front", "tau_hip_back", "tau_knee_back")
GRF_NAMES = ("f_front_x", "f_front_z", "f_back_x", "f_back_z")

# Indices into q / x.
IX, IZ, IPITCH = 0, 1, 2
IHIP_F, IKNEE_F, IHIP_B, IKNEE_B = 3, 4, 5, 6
BASE_DOFS = slice(0, 3)
JOINT_DOFS = slice(3, 7)
Q_SLICE = slice(0, NQ)
V_SLICE = slice(NQ, NX)
IVX = NQ + IX
"""Index of the forward velocity in ``x``."""
IVZ = NQ + IZ
"""Index of the vertical velocity in ``x``."""

FRONT = 0
BACK = 1
FEET = (FRONT, BACK)
FOOT_NAMES = ("front", "back")
FOOT_SIGN = (1.0, -1.0)
"""+1 for the front leg (hip at +x of the trunk origin), -1 for the back leg."""
FOOT_JOINTS = ((IHIP_F, IKNEE_F), (IHIP_B, IKNEE_B))
"""Indices in q of each foot's (hip, knee)."""
FOOT_U = ((0, 1), (2, 3))
"""Indices in u of each foot's (hip, knee) torque."""


class Mode(enum.IntEnum):
    """Contact mode: bit ``1 << foot`` set when that foot is on the ground."""

    FLIGHT = 0
    FRONT_STANCE = 1
    BACK_STANCE = 2
    DOUBLE_STANCE = 3

    @property
    def feet(self) -> tuple[int, ...]:
        """Indices of the feet in contact, in ``FEET`` order."""
        return tuple(f for f in FEET if self.value & (1 << f))

    def in_contact(self, foot: int) -> bool:
        """True when ``foot`` is on the ground in this mode."""
        return bool(self.value & (1 << foot))

    @property
    def short(self) -> str:
        return _SHORT[self]


_SHORT = {Mode.FLIGHT: "FL", Mode.FRONT_STANCE: "FS", Mode.BACK_STANCE: "BS", Mode.DOUBLE_STANCE: "DS"}


def as_mode(value, name: str = "mode") -> Mode:
    """``Mode(value)`` with an error that names the argument (bools are refused)."""
    if isinstance(value, bool):
        raise TypeError(f"{name} must be a Mode or an int, got a bool")
    try:
        return Mode(value)
    except (ValueError, TypeError):
        raise ValueError(f"{name} must be one of {[int(m) for m in Mode]} "
                         f"({', '.join(m.name for m in Mode)}), got {value!r}") from None


def mode_from_contacts(front: bool, back: bool) -> Mode:
    """The mode whose feet in contact are exactly ``front`` / ``back``."""
    return Mode((1 if front else 0) | (2 if back else 0))


def touchdown_feet(before: Mode, after: Mode) -> tuple[int, ...]:
    """Feet that are in contact in ``after`` but not in ``before`` (they touch down at the switch)."""
    return tuple(f for f in FEET if after.in_contact(f) and not before.in_contact(f))


def grf_slice(foot: int) -> slice:
    """Slice of ``grf`` (4,) holding ``[f_x, f_z]`` of ``foot``."""
    return slice(2 * foot, 2 * foot + 2)


def split_state(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Views ``(q (7,), v (7,))`` of a state ``x (14,)``; or of ``(..., 14)`` batches."""
    return x[..., Q_SLICE], x[..., V_SLICE]

"""The paper's initial state and the per-mode reference postures, converted to ground at z = 0.

The authors' code measures z from the hip height with straight legs, ground at z = -0.404 m
(original_code_facts §1.1); here the ground is z = 0, so every z gets ``+ leg_length`` (0.404 m).
"""

from __future__ import annotations

import functools
import math
import numbers

import numpy as np

from hsddp_gym.core.conventions import IVX, IVZ, NQ, NX, Mode, as_mode
from hsddp_gym.core.params import DEFAULT_PARAMS, RobotParams

_PI = math.pi


def paper_initial_state(params: RobotParams = DEFAULT_PARAMS) -> np.ndarray:
    """The initial state of every version of the authors' code (original_code_facts §3.3): mid back stance,
    back foot 0.2 mm above the ground, front foot 0.142 m up, moving forward at 0.90 m/s.

    Returns:
        x0 (14,).
    """
    if not isinstance(params, RobotParams):
        raise TypeError(f"params must be a RobotParams, got {type(params).__name__}")
    q0 = np.array([0.0, -0.1093, -0.1542, 1.0957, -2.2033, 0.9742, -1.7098])
    q0[1] += params.leg_length
    v0 = np.array([0.9011, 0.2756, 0.7333, 0.0446, 0.0009, 1.3219, 2.7346])
    return np.concatenate([q0, v0])


# Terminal reference postures per mode at the END of the mode (original_code_facts §3.4):
# (z in the code's frame, pitch, hip_f, knee_f, hip_b, knee_b, zdot).
_END_POSTURES = {
    "BS": (-0.1432, -_PI / 25, 0.35 * _PI, -0.65 * _PI, 0.35 * _PI, -0.60 * _PI, +1.0),
    "FL_front_td": (-0.1418, +_PI / 35, 0.20 * _PI, -0.58 * _PI, 0.25 * _PI, -0.70 * _PI, -1.0),
    "FS": (-0.1325, -_PI / 40, 0.33 * _PI, -0.48 * _PI, 0.33 * _PI, -0.75 * _PI, +1.0),
    "FL_back_td": (-0.1490, -_PI / 25, 0.35 * _PI, -0.70 * _PI, 0.25 * _PI, -0.60 * _PI, -1.0),
}


MAX_HEIGHT_OFFSET = 0.1
"""The largest ``height_offset`` [m] a reference posture accepts (either way): the legs' reach."""


def check_height_offset(value, name: str = "height_offset") -> float:
    """``value`` as a float if it is a real number in ``[-MAX_HEIGHT_OFFSET, MAX_HEIGHT_OFFSET]`` [m], else a
    ValueError naming ``name`` (bools, strings and NaN included)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (
            -MAX_HEIGHT_OFFSET <= float(value) <= MAX_HEIGHT_OFFSET):
        raise ValueError(f"{name} must be a number in [-{MAX_HEIGHT_OFFSET}, {MAX_HEIGHT_OFFSET}] [m], got {value!r}")
    return float(value)


@functools.lru_cache(maxsize=64)
def _raised_posture(key: str, height_offset: float, params: RobotParams) -> tuple:
    """``_END_POSTURES[key]`` with the trunk ``height_offset`` [m] higher and every foot where it was: the four joint
    angles by Newton's method on the feet's world positions (pitch and the foot positions unchanged)."""
    from hsddp_gym.core.model import CheetahModel

    z, pitch, hf, kf, hb, kb, zdot = _END_POSTURES[key]
    model = CheetahModel(params)
    q = np.array([0.0, z + params.leg_length, pitch, hf, kf, hb, kb])
    feet = model.foot_positions(q)
    q[1] += height_offset
    try:
        q = model.place_feet(q, feet)
    except ValueError:
        raise ValueError(f"height_offset {height_offset!r} m: the feet of the {key} posture are out of the legs' "
                         "reach") from None
    return (z + height_offset, pitch, *q[3:].tolist(), zdot)


def end_of_mode_reference(mode: Mode, touchdown_foot: int | None, speed: float = 1.0,
                          z_velocity: str = "paper", params: RobotParams = DEFAULT_PARAMS,
                          height_offset: float = 0.0) -> np.ndarray:
    """The reference state at the end of a bounding mode (original_code_facts §3.4).

    Each reference puts exactly the relevant foot on the ground: the stance foot at the end of a stance
    mode, the touching-down foot at the end of a flight mode.

    ``DOUBLE_STANCE`` (not in the authors' gait; the MPC plans one when a swing foot lands before the stance
    foot has lifted off, e.g. after a downward push) ends when the other foot lifts off: its reference is the
    touchdown posture of the foot that stays (the ``FLIGHT`` reference landing it) with zero vertical velocity,
    the trunk's fall stopped.

    Args:
        mode: ``BACK_STANCE``, ``FRONT_STANCE``, ``FLIGHT`` or ``DOUBLE_STANCE``.
        touchdown_foot: for ``FLIGHT``, the foot that touches down at its end (``FRONT`` after back stance,
            ``BACK`` after front stance); for ``DOUBLE_STANCE``, the foot that stays on the ground after it;
            ignored for single stance modes.
        speed: desired forward speed [m/s] (paper: 1.0).
        z_velocity: ``"paper"`` (default) uses 0, as the paper's text says ("all desired joint velocities and
            the desired body vertical velocity are set to zero"); ``"code"`` uses the authors' +1 m/s after
            stance / -1 m/s before touchdown.
        height_offset: the trunk this much higher [m] than in the authors' posture, each foot where that posture
            has it (the joint angles by inverse kinematics; pitch unchanged). 0 (default): the authors' postures.
            The MPC plans a gait 4 cm higher (``PlanOptions.height_offset``): more room to the ground after a push.
    Returns:
        x_ref (14,): zero x position, joint and pitch rates.
    """
    from hsddp_gym.core.conventions import BACK, FRONT

    mode = as_mode(mode, "mode")
    if mode == Mode.BACK_STANCE:
        key = "BS"
    elif mode == Mode.FRONT_STANCE:
        key = "FS"
    elif mode in (Mode.FLIGHT, Mode.DOUBLE_STANCE) and touchdown_foot == FRONT:
        key = "FL_front_td"
    elif mode in (Mode.FLIGHT, Mode.DOUBLE_STANCE) and touchdown_foot == BACK:
        key = "FL_back_td"
    else:
        raise ValueError(f"no bounding reference for mode={mode!r} with touchdown_foot={touchdown_foot!r}")
    if isinstance(speed, bool) or not isinstance(speed, numbers.Real) or not math.isfinite(float(speed)):
        raise ValueError(f"speed must be a finite number [m/s], got {speed!r}")
    if not isinstance(params, RobotParams):
        raise TypeError(f"params must be a RobotParams, got {type(params).__name__}")
    if z_velocity not in ("code", "paper"):
        raise ValueError(f"z_velocity must be 'code' or 'paper', got {z_velocity!r}")
    height_offset = check_height_offset(height_offset)
    if height_offset == 0.0:
        z, pitch, hf, kf, hb, kb, zdot = _END_POSTURES[key]
    else:
        z, pitch, hf, kf, hb, kb, zdot = _raised_posture(key, height_offset, params)
    x = np.zeros(NX)
    x[:NQ] = (0.0, z + params.leg_length, pitch, hf, kf, hb, kb)
    x[IVX] = speed
    x[IVZ] = zdot if z_velocity == "code" and mode != Mode.DOUBLE_STANCE else 0.0
    return x

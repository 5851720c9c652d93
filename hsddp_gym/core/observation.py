"""The observation of ``hsddp_gym/Bounding-v0`` and its documented inverse map.

Policies (learned or planner-based) act from observations only; this module is the one place that
defines the layout, builds observations from a state, and maps an observation back to a state, a contact
mode and a gait phase.

Layout (float32), with ``exclude_current_positions_from_observation=True`` (the default, 17 entries)::

    index  name          meaning                                            unit     bound
    0      z             trunk height (trunk origin, ground at z = 0)      m        [-2, 10]
    1      pitch         trunk pitch, positive nose-down                   rad      +-100
    2..5   joints        hip_front, knee_front, hip_back, knee_back        rad      +-100
    6      vx            forward velocity                                  m/s      +-100
    7      vz            vertical velocity                                 m/s      +-100
    8      pitch rate                                                      rad/s    +-1000
    9..12  joint rates   same order as the joints                          rad/s    +-1000
    13     contact_front 1.0 when the ground pushes the front foot          -        [0, 1]
    14     contact_back  1.0 when the ground pushes the back foot           -        [0, 1]
    15     sin(phase)    phase = 2 pi t / gait_period                      -        [-1, 1]
    16     cos(phase)                                                      -        [-1, 1]

With ``exclude_current_positions_from_observation=False`` the trunk ``x`` position [m] (bound +-1e4) is
prepended and every index above shifts by one (18 entries). The order of positions and velocities is the
state order of [`hsddp_gym.core.conventions`][hsddp_gym.core.conventions]. Values outside the bounds are clipped (the
exact state is always in the env's ``info["qpos"]`` / ``info["qvel"]``); the bounds are far outside anything a healthy
episode reaches.

Contact flags: after a step, the flag of a foot is 1 when the ground pushed on it (normal impulse > 0)
during the last 1 ms simulation step of the control step -- the physical contact, so a stance foot whose
load vanishes is released at once (lift-off) and a landing foot is flagged from its impact on. Right
after a reset (before any step) a foot counts as in contact when its height is at most
[`RESET_CONTACT_HEIGHT`][RESET_CONTACT_HEIGHT] (1 mm). ``t`` is the episode clock [s] (0 at reset unless the ``time``
reset option is given).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, NQ, NV, NX, Mode, mode_from_contacts
from hsddp_gym.util.validation import check_positive

RESET_CONTACT_HEIGHT = 1e-3
"""Right after a reset a foot at most this high [m] is flagged as in contact."""

_POS_BOUND = 1e4
_Z_BOUNDS = (-2.0, 10.0)
_ANGLE_BOUND = 100.0
_LIN_VEL_BOUND = 100.0
_ANG_VEL_BOUND = 1000.0


@dataclasses.dataclass(frozen=True)
class ObservationLayout:
    """Where each quantity sits in the observation vector.

    Args:
        exclude_current_positions: drop the trunk ``x`` position (default True, as HalfCheetah-v5).

    Attributes:
        size: observation length (17, or 18 with ``x``).
        qpos: slice of the positions in the observation (``q[1:]`` (6,) or ``q`` (7,)).
        qvel: slice of the velocities ``v`` (7,).
        contact: slice of the contact flags ``[front, back]`` (2,).
        phase: slice of ``[sin, cos]`` of the gait phase (2,).
        skipped_qpos: number of leading entries of ``q`` left out (1 or 0).
    """

    exclude_current_positions: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.exclude_current_positions, (bool, np.bool_)):
            raise TypeError("exclude_current_positions must be a bool, "
                            f"got {type(self.exclude_current_positions).__name__}")

    @property
    def skipped_qpos(self) -> int:
        return 1 if self.exclude_current_positions else 0

    @property
    def qpos(self) -> slice:
        return slice(0, NQ - self.skipped_qpos)

    @property
    def qvel(self) -> slice:
        start = NQ - self.skipped_qpos
        return slice(start, start + NV)

    @property
    def contact(self) -> slice:
        start = NQ - self.skipped_qpos + NV
        return slice(start, start + 2)

    @property
    def phase(self) -> slice:
        start = NQ - self.skipped_qpos + NV + 2
        return slice(start, start + 2)

    @property
    def size(self) -> int:
        return NQ - self.skipped_qpos + NV + 4

    @property
    def structure(self) -> dict:
        """``{"skipped_qpos", "qpos", "qvel", "contact", "phase"}`` sizes (MuJoCo-v5 style)."""
        return {"skipped_qpos": self.skipped_qpos, "qpos": NQ - self.skipped_qpos, "qvel": NV, "contact": 2,
                "phase": 2}

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` float32 arrays (size,) of the observation box."""
        q_high = np.array([_POS_BOUND, _Z_BOUNDS[1]] + [_ANGLE_BOUND] * 5)
        q_low = np.array([-_POS_BOUND, _Z_BOUNDS[0]] + [-_ANGLE_BOUND] * 5)
        v_high = np.array([_LIN_VEL_BOUND] * 2 + [_ANG_VEL_BOUND] * 5)
        high = np.concatenate([q_high[self.skipped_qpos:], v_high, [1.0, 1.0, 1.0, 1.0]])
        low = np.concatenate([q_low[self.skipped_qpos:], -v_high, [0.0, 0.0, -1.0, -1.0]])
        return low.astype(np.float32), high.astype(np.float32)


DEFAULT_LAYOUT = ObservationLayout()


def build_observation(x: np.ndarray, contact, time: float, gait_period: float,
                      layout: ObservationLayout = DEFAULT_LAYOUT, out: np.ndarray | None = None) -> np.ndarray:
    """The observation (``layout.size``,) float32 of a state.

    Args:
        x: state (14,). contact: flags ``[front, back]`` (2,) (bools or 0/1).
        time: time since the reset [s]. gait_period: period of the phase clock [s] (> 0).
        layout: the layout. out: optional float32 output buffer (``layout.size``,).
    Returns:
        The observation, clipped to ``layout.bounds()`` (NaN entries of an invalid state become 0).
    """
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (NX,):
        raise ValueError(f"x must have shape ({NX},), got {x.shape}")
    if not isinstance(layout, ObservationLayout):
        raise TypeError(f"layout must be an ObservationLayout, got {type(layout).__name__}")
    gait_period = check_positive(gait_period, "gait_period")
    obs = np.empty(layout.size, dtype=np.float32) if out is None else out
    fill_observation(obs, x, bool(contact[FRONT]), bool(contact[BACK]), float(time) / gait_period,
                     layout.exclude_current_positions)
    return obs


def fill_observation(obs: np.ndarray, x: np.ndarray, front: bool, back: bool, cycles: float,
                     exclude_current_positions: bool = True) -> None:
    """Unchecked fast path of [`build_observation`][build_observation] (the env's hot loop).

    Args:
        obs: float32 output (17,) or (18,). x: state (14,) float64. front, back: contact flags.
        cycles: ``t / gait_period``. exclude_current_positions: the layout flag.
    """
    skip = 1 if exclude_current_positions else 0
    nq = NQ - skip
    obs[:nq] = x[skip:NQ]
    obs[nq:nq + NV] = x[NQ:]
    c = nq + NV
    obs[c] = 1.0 if front else 0.0
    obs[c + 1] = 1.0 if back else 0.0
    angle = 2.0 * math.pi * cycles
    obs[c + 2] = math.sin(angle)
    obs[c + 3] = math.cos(angle)
    low, high = _bounds_cache(exclude_current_positions)
    np.minimum(obs, high, out=obs)
    np.maximum(obs, low, out=obs)
    total = float(obs.sum())
    if total != total:  # NaN from an invalid (blown-up) state: keep the observation inside the box
        np.nan_to_num(obs, copy=False, nan=0.0)


_BOUNDS = {}


def _bounds_cache(exclude_current_positions: bool) -> tuple[np.ndarray, np.ndarray]:
    key = bool(exclude_current_positions)
    if key not in _BOUNDS:
        _BOUNDS[key] = ObservationLayout(key).bounds()
    return _BOUNDS[key]


def state_from_observation(obs, layout: ObservationLayout = DEFAULT_LAYOUT,
                           x_position: float = 0.0) -> tuple[np.ndarray, Mode, float]:
    """Invert [`build_observation`][build_observation].

    Args:
        obs: an observation (``layout.size``,) (any float dtype).
        layout: the layout the observation was built with (the env's ``observation_layout``).
        x_position: trunk ``x`` [m] to put in the state when the layout excludes it (default 0; the
            dynamics, the heuristic controller and the planner's feedback are invariant to it).
    Returns:
        ``(x (14,) float64, mode, phase)``: the state (float32 precision), the contact mode from the
        flags (a flag counts when > 0.5), and the gait phase as a fraction of the period in ``[0, 1)``
        (``phase * gait_period`` is the time since the last cycle start of the clock).
    """
    if not isinstance(layout, ObservationLayout):
        raise TypeError(f"layout must be an ObservationLayout, got {type(layout).__name__}")
    o = np.asarray(obs, dtype=np.float64)
    if o.shape != (layout.size,):
        raise ValueError(f"obs must have shape ({layout.size},) for this layout, got {o.shape}")
    if not np.all(np.isfinite(o)):
        raise ValueError("obs must be finite")
    x = np.empty(NX)
    if layout.exclude_current_positions:
        x[0] = float(x_position)
    x[layout.skipped_qpos:NQ] = o[layout.qpos]
    x[NQ:] = o[layout.qvel]
    c = layout.contact.start
    mode = mode_from_contacts(o[c] > 0.5, o[c + 1] > 0.5)
    p = layout.phase.start
    phase = (math.atan2(o[p], o[p + 1]) / (2.0 * math.pi)) % 1.0
    if phase >= 1.0:  # atan2 rounding just below 2 pi
        phase = 0.0
    return x, mode, float(phase)


def phase_of_time(time: float, gait_period: float) -> float:
    """The gait phase fraction in ``[0, 1)`` of the clock at ``time`` [s]."""
    gait_period = check_positive(gait_period, "gait_period")
    return float((time / gait_period) % 1.0)

"""The constants of the tasks beyond the bound that both the envs (``hsddp_gym.envs``) and the planners
(``hsddp_gym.planners.motions``) need: the pronk's cycle, the standing posture, the gait transitions' double stances,
the jumps' obstacles, and the episode lengths of the registered envs.

Pure Python (no NumPy at import): the task registry ([`hsddp_gym.registry`][hsddp_gym.registry]), which ``import
hsddp_gym`` reads, imports this module.
"""

from __future__ import annotations

import numbers

SPEED_RANGE = (0.5, 1.5)
"""Target speeds [m/s] the motions are planned and tested for (the pronking task's target speeds)."""

PRONK_DURATIONS = (0.10, 0.08)
"""Double stance and flight of a pronk cycle [s]."""
PRONK_HEIGHT = 0.26
"""Trunk height of the pronk's lift-off and touchdown postures [m] (the bound's postures: 0.255-0.272 m)."""
STAND_HEIGHT = 0.26
"""Trunk height of the standing posture [m] (the backflip's start, the stand-to-bound's)."""
STAND_DURATION = 0.25
"""The double stance that starts from rest (stand to bound) [s]."""
STOP_DURATION = 0.40
"""The double stance that ends at rest (bound to stop) [s]."""

JUMPS = ("gap_jump", "box_jump")
"""The jumps: over a gap, onto a box, from a bound and bounding on."""
GAP_WIDTH = 0.3
"""Width of the gap of ``"gap_jump"`` [m]."""
BOX_HEIGHT = 0.1
"""Height of the box of ``"box_jump"`` [m]."""
BOX_LENGTH = 3.0
"""Length of the box of ``"box_jump"`` [m] (longer than the bounding on it)."""
JUMP_EDGE_LEAD = 0.05
"""The terrain's near edge this far ahead of the trunk's expected x at the take-off back stance's start [m]."""
JUMP_APPROACH_CYCLES = 2
"""Bounding cycles before a jump (the jump envs' start at 1 m/s: the plans' two cycles)."""

TRANSITIONS = ("stand_to_bound", "bound_pronk_bound", "bound_to_stop")
"""The gait transitions."""

BOUNDING_MAX_EPISODE_STEPS = 1000
"""1000 control steps = 5 s at the default 200 Hz (about 17 bounding cycles)."""
PRONKING_MAX_EPISODE_STEPS = 1000
"""1000 control steps = 5 s at the default 200 Hz (about 28 pronk cycles)."""
BACKFLIP_MAX_EPISODE_STEPS = 400
"""400 control steps = 2 s at the default 200 Hz (the flip and its landing take 1.05 s, then a hold)."""
JUMP_MAX_EPISODE_STEPS = 400
"""400 control steps = 2 s at the default 200 Hz (the approach and the jump take 1 s, then bounding on)."""
BOUND_PUSH_WINDOW = (1.0, 4.0)
"""When a push of the bound comes (``RandomPush``'s default ``time_range``, Bounding-v0 and Terrain-v0): ``t ~ U(1, 4)``
s of the 5 s episode, past the start's transient and at least a second before its end."""
BOUND_PUSH_SIZE = (0.8, 0.8, 5.0)
"""The largest trunk-velocity change of a push of the bound (``RandomPush``'s default ``max_delta_v``), ``[dvx, dvz,
dpitch_rate]`` [m/s, m/s, rad/s]."""
MOTION_PUSH_SIZE = (0.4, 0.4, 3.0)
"""The largest trunk-velocity change of a push of the planned motions (pronk, backflip, jumps, transitions), ``[dvx,
dvz, dpitch_rate]`` [m/s, m/s, rad/s]: their plan-tracking experts follow one plan without re-planning, and a push
lands within a motion of about a second rather than in a steady gait."""

TRANSITION_MAX_EPISODE_STEPS = {"stand_to_bound": 300, "bound_pronk_bound": 400, "bound_to_stop": 300}
"""Control steps per episode of the gait transitions (1.5 s, 2 s, 1.5 s at 200 Hz: the plan and at least 0.4 s
more)."""


def check_speed(speed) -> float:
    """``speed`` [m/s] as a float if it is a real number in [`SPEED_RANGE`][SPEED_RANGE], else ``ValueError`` naming
    it."""
    lo, hi = SPEED_RANGE
    if isinstance(speed, bool) or not isinstance(speed, numbers.Real) or not lo <= float(speed) <= hi:
        raise ValueError(f"speed must be a number in [{lo}, {hi}] m/s, got {speed!r}")
    return float(speed)


def jump_terrain(motion: str, speed: float = 1.0, cycles: int = JUMP_APPROACH_CYCLES):
    """The [`Terrain`][hsddp_gym.core.terrain.Terrain] of a jump ([`JUMPS`][JUMPS]) after ``cycles`` bounding cycles at
    ``speed`` [m/s] from the paper's initial state (x = 0): its near edge [`JUMP_EDGE_LEAD`][JUMP_EDGE_LEAD] ahead of
    where the trunk is, at ``speed``, when the take-off back stance starts (``t = 4 cycles`` bound phases);
    ``"gap_jump"``: a gap of [`GAP_WIDTH`][GAP_WIDTH]; ``"box_jump"``: a box of [`BOX_HEIGHT`][BOX_HEIGHT], its near
    edge [`GAP_WIDTH`][GAP_WIDTH] / 2 further (the middle of where the gap would be), [`BOX_LENGTH`][BOX_LENGTH] long.
    The jump envs' terrain is the one at 1 m/s after [`JUMP_APPROACH_CYCLES`][JUMP_APPROACH_CYCLES] cycles."""
    from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
    from hsddp_gym.core.terrain import Terrain
    from hsddp_gym.util.validation import check_int

    if motion not in JUMPS:
        raise ValueError(f"motion must be one of {JUMPS}, got {motion!r}")
    speed = check_speed(speed)
    cycles = check_int(cycles, "cycles", minimum=1)
    near = speed * cycles * sum(PAPER_BOUNDING_DURATIONS) + JUMP_EDGE_LEAD
    if motion == "gap_jump":
        return Terrain.gap(near, near + GAP_WIDTH)
    edge = near + GAP_WIDTH / 2.0
    return Terrain.box(edge, edge + BOX_LENGTH, BOX_HEIGHT)

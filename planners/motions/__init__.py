"""HS-DDP motions beyond the bound: a pronk, gait transitions, jumps and a backflip, as planning tasks.

[`problems`][hsddp_gym.planners.motions.problems] builds each motion's phases, references, problem and warm start;
[`planning`][hsddp_gym.planners.motions.planning] solves them (``plan_pronk``, ``plan_transition``, ``plan_jump``,
``plan_backflip``, ``plan_motion`` by name, the experts' held plans ``plan_*_held``) and checks every plan's limits;
[`references`][hsddp_gym.planners.motions.references] solves the motions the MPC re-plans online on its grid and
builds their MPC.
The constants the envs share are [`hsddp_gym.core.task_constants`][hsddp_gym.core.task_constants]'.
"""

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines (or imports from the core's task constants)
    "problems": (
        "MOTIONS", "TRANSITIONS", "SPEED_RANGE", "PRONK_DURATIONS", "JOINT_LIMITS", "MotionPhase", "leg_posture",
        "double_stance_state", "pronk_reference", "stand_reference", "pronk_phases", "bound_phases",
        "motion_problem", "pronk_problem", "transition_problem", "motion_warm_start", "JUMPS", "GAP_WIDTH",
        "BOX_HEIGHT", "JUMP_FLIGHT", "jump_terrain", "jump_problem", "backflip_problem", "BACKFLIP_OPTIONS",
        "PRONK_HEIGHT", "STAND_HEIGHT", "STAND_DURATION", "STOP_DURATION", "STOP_TERMINAL_WEIGHTS",
        "JUMP_SPEED_FACTOR", "LANDING_MARGIN", "PLACEMENT_WEIGHT", "SWITCHING_TOLERANCE", "BACKFLIP_DURATIONS",
        "BACKFLIP_PITCH", "BACKFLIP_PITCH_RATE", "BACKFLIP_MOMENTUM", "BACKFLIP_PUSH_VZ", "BACKFLIP_TUCK",
        "BACKFLIP_KNEE_CLEARANCE", "BACKFLIP_FOOT_CLEARANCE", "check_speed",
    ),
    "planning": (
        "motion_limits", "plan_backflip", "plan_pronk", "plan_transition", "plan_jump", "plan_motion",
        "plan_backflip_held", "plan_jump_held", "plan_transition_held",
    ),
    "references": ("Motion", "MOTION_PROBLEMS", "motion_reference", "motion_mpc_policy"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)

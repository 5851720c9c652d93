"""The tasks' experts: each one HS-DDP plan tracked by a
[`PlanTrackingPolicy`][hsddp_gym.planners.policies.tracking_policy.PlanTrackingPolicy], configured by its touchdown rule
([`hsddp_gym.planners.policies.touchdown`][hsddp_gym.planners.policies.touchdown]) and what comes after the plan. No
re-planning but the bounding expert's MPC.

* **Bounding** ([`bounding_expert`][bounding_expert]; ``hsddp_gym/Bounding-v0``): the plan of paper task 1 from the
env's initial
  state (reset option ``{"state": plan.X[0]}``), every contact flag counted; when it ends (the touchdown after its
  last flight, or its last knot) the MPC picks up the gait from the observed contacts (``HandOver``).
* **Pronking** ([`pronking_expert`][pronking_expert]; ``plan_pronk``: ``DS(T_s/2) FL (DS FL) x (cycles - 1) -> DS``):
touchdowns
  count for feet seen airborne during the flight, or half-way through it (``SeenAirborne``). A plan covers a few
  cycles and an episode needs many more, so at the touchdown that ends the plan the cursor returns to the start of
  one of its middle double stances ([`PRONK_LOOP_PHASE`][PRONK_LOOP_PHASE], ``RepeatCycle``): the plan's steady cycles,
  whose touchdown and lift-off states repeat to a few mm and mrad, are played periodically.
* **Backflip** ([`backflip_expert`][backflip_expert]; ``plan_backflip_held``: ``DS(250 ms) BS(100 ms) FL(400 ms) DS(300
ms)`` with the feedback gains of a control held for the env's 5 ms control period): touchdowns count for feet seen 2 cm
  clear (``FootClearance``); when the plan runs out (its last double stance ends at rest, pitch ``-2 pi``) its last
  posture is held (``HoldPosture``).
* **Jumps** ([`jump_expert`][jump_expert]; ``plan_jump_held``: from the paper's initial state two bounding cycles at 1
m/s, the jump ``BS(80 ms) FL(250 ms) FS(72 ms) FL(72 ms)`` and two bounding cycles on the far side): touchdowns as the
  backflip's. The observation has no world x, so the expert, like the plan, places its feet by time and the env must
  put the terrain where the plan has it. The first bounding cycle after the jump ([`JUMP_LOOP`][JUMP_LOOP], phases
  12-15) is then played periodically, so the robot bounds on with the plan's own gains. The plan's last cycle is never
  played: it ends on a terminal cost, not on a periodic state (its landing is about 5 cm lower than the cycle's), and a
  loop from there starts every cycle 0.3 rad of joint error off the plan (twice the tracking error, and the trunk
  sagging to 0.15 m in the MuJoCo twin).
* **Gait transitions** ([`transition_expert`][transition_expert]; ``plan_transition_held``: 1 m/s,
  the task registry's cycles per gait segment): stand to bound plays its first cycle at 1 m/s
  periodically (phases 5-8 of a plan with a third cycle: looping the plan's last cycle, which ends on a terminal
  cost, falls within two loops); bound-pronk-bound its first bounding cycle after the pronk (phases 13-16), as the
  jumps' expert; bound to stop holds its last posture, as the backflip's ([`TRANSITION_LOOPS`][TRANSITION_LOOPS]). The
  pronk's 80 ms flights lift the feet only about 1 cm, so the touchdown clearance comes from the plan
  ([`plan_clearance`][hsddp_gym.planners.policies.touchdown.plan_clearance]: 2 cm, or half the lowest peak the landing
  feet reach during a flight of the plan if lower).
"""

from __future__ import annotations

from hsddp_gym.core.model import CheetahModel
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.touchdown import FootClearance, SeenAirborne, plan_clearance
from hsddp_gym.planners.policies.tracking_policy import (
    HOLD_KD,
    HOLD_KP,
    HandOver,
    HoldPosture,
    PlanTrackingPolicy,
    RepeatCycle,
)

PRONK_LOOP_PHASE = 2
"""The pronking expert's ``loop_phase``: the second cycle's double stance."""
JUMP_LOOP = (12, 16)
"""The jump expert's ``(loop_phase, loop_end)``: the back stance of the first bounding cycle after the jump (two
cycles of 4 phases, then the jump's 4 phases: phases 12-15 are a steady cycle on the far side), and the start of the
plan's last cycle (the back foot's touchdown that ends the looped cycle)."""
TRANSITION_LOOPS = {"stand_to_bound": (5, 9), "bound_pronk_bound": (13, 17), "bound_to_stop": (None, None)}
"""Per gait transition, the transition expert's ``(loop_phase, loop_end)`` (``(None, None)``: the plan finishes,
then its last posture is held)."""


def bounding_expert(interface: EnvInterface, solution, fallback: Policy | None = None) -> PlanTrackingPolicy:
    """The bounding expert: ``solution`` tracked with every contact flag counted, then ``fallback`` (None: the MPC
    with default options)."""
    return PlanTrackingPolicy(interface, solution, after_plan=HandOver(fallback))


def pronking_expert(interface: EnvInterface, solution, loop_phase: int = PRONK_LOOP_PHASE) -> PlanTrackingPolicy:
    """The pronking expert: a pronk plan ([`plan_pronk`][hsddp_gym.planners.motions.planning.plan_pronk], at least 3
    cycles; the env should start at its ``X[0]``, as ``hsddp_gym/Pronking-v0`` does when planned at its target speed)
    tracked with touchdowns counted for feet seen airborne (or half-way through the phase), its cycles from the double
    stance ``loop_phase`` to the plan's end repeated."""
    return PlanTrackingPolicy(interface, solution, touchdown=SeenAirborne(), after_plan=RepeatCycle(loop_phase))


def backflip_expert(interface: EnvInterface, solution, hold_kp: float = HOLD_KP,
                    hold_kd: float = HOLD_KD) -> PlanTrackingPolicy:
    """The backflip expert: a backflip plan (``hsddp_gym.planners.motions.plan_backflip_held`` with ``hold`` =
    control period / 1 ms; ``hsddp_gym/Backflip-v0`` starts at its ``X[0]``) tracked with touchdowns counted for feet
    seen 2 cm clear, then its last posture held with the joint gains ``hold_kp`` [N m/rad], ``hold_kd`` [N m s/rad]."""
    return PlanTrackingPolicy(interface, solution, touchdown=FootClearance(),
                              after_plan=HoldPosture(hold_kp, hold_kd))


def jump_expert(interface: EnvInterface, solution, loop_phase: int = JUMP_LOOP[0],
                loop_end: int = JUMP_LOOP[1]) -> PlanTrackingPolicy:
    """The jump expert: a jump plan (``hsddp_gym.planners.motions.plan_jump_held`` with ``hold`` = control period /
    1 ms; the env starts at its ``X[0]`` over the plan's terrain) tracked with touchdowns counted for feet seen 2 cm
    clear, then its cycle ``loop_phase .. loop_end - 1`` repeated."""
    return PlanTrackingPolicy(interface, solution, touchdown=FootClearance(),
                              after_plan=RepeatCycle(loop_phase, loop_end))


def transition_expert(interface: EnvInterface, solution, task: str, hold_kp: float = HOLD_KP,
                      hold_kd: float = HOLD_KD) -> PlanTrackingPolicy:
    """The gait-transition expert of ``task`` (one of [`TRANSITION_LOOPS`][TRANSITION_LOOPS]): a transition plan
    (``hsddp_gym.planners.motions.plan_transition_held`` with ``hold`` = control period / 1 ms and the registry's
    cycles, ``hsddp_gym.registry.TASKS[task].plan_kwargs``; the transition envs start at its ``X[0]``) tracked with
    touchdowns counted for feet seen [`plan_clearance`][hsddp_gym.planners.policies.touchdown.plan_clearance] clear,
    then its bounding cycle repeated or (bound to stop) its last posture held with the joint gains ``hold_kp``,
    ``hold_kd``."""
    if task not in TRANSITION_LOOPS:
        raise ValueError(f"task must be one of {tuple(TRANSITION_LOOPS)}, got {task!r}")
    if solution is None:
        raise ValueError("solution must be a Solution (the transition plan to track)")
    loop_phase, loop_end = TRANSITION_LOOPS[task]
    hold = HoldPosture(hold_kp, hold_kd)
    after = hold if loop_phase is None else RepeatCycle(loop_phase, loop_end)
    robot = CheetahModel()
    return PlanTrackingPolicy(interface, solution, touchdown=FootClearance(plan_clearance(solution, robot), robot),
                              after_plan=after)


__all__ = ["PRONK_LOOP_PHASE", "JUMP_LOOP", "TRANSITION_LOOPS", "bounding_expert",
           "pronking_expert", "backflip_expert", "jump_expert", "transition_expert"]

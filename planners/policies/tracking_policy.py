"""The plan-tracking policy: one offline HS-DDP plan tracked with its feedback law, then what comes after the plan.

[`PlanTrackingPolicy`][PlanTrackingPolicy] acts with ``u = U_k + K_k (x - X_k)`` (paper eq. 8, eps = 0, the trunk's x
not fed back) at the cursor of a [`PlanTracker`][hsddp_gym.planners.policies.tracking.PlanTracker], from observations
only: each step the observed contacts synchronize the cursor (its touchdown rule,
[`hsddp_gym.planners.policies.touchdown`][hsddp_gym.planners.policies.touchdown]), the law at the cursor acts, and the
cursor advances by the env's control period. Two settings make a task's expert
([`hsddp_gym.planners.policies.experts`][hsddp_gym.planners.policies.experts]):

* ``touchdown``: which observed touchdowns move the cursor to the next phase (contact flags, feet seen airborne,
  feet seen clear of the ground);
* ``after_plan``: what happens when the plan is over:

  * [`HandOver`][HandOver]: another policy takes over (by default the MPC, which picks up the gait from the observed
    contacts); the plan's last knot acts on the step whose observation ends the plan, the other policy from the
    next step on;
  * [`HoldPosture`][HoldPosture]: the plan's last control plus a joint PD to its last knot's joint angles, from the step
    whose observation ends the plan (or whose cursor reaches the plan's end);
  * [`RepeatCycle`][RepeatCycle]: the plan is never over: the tracker plays the cycle ``loop_phase .. loop_end - 1``
    periodically.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.touchdown import TouchdownRule
from hsddp_gym.planners.policies.tracking import PlanTracker, tracking_error
from hsddp_gym.util.validation import check_int, check_positive

HOLD_KP = 50.0
"""[`HoldPosture`][HoldPosture]'s joint stiffness [N m/rad]."""
HOLD_KD = 0.8
"""[`HoldPosture`][HoldPosture]'s joint damping [N m s/rad] (the feet on the ground carry the trunk, so more than a
swinging leg's 0.4 at 200 Hz is stable)."""


class AfterPlan:
    """Base class of what acts once the plan is over (module docstring).

    Attributes:
        acts_on_ending_step: whether it acts already on the step whose observation ends the plan (False: the plan's
            last knot acts once more).
    """

    acts_on_ending_step = True

    def loop(self) -> tuple[int | None, int | None]:
        """The tracker's ``(loop_phase, loop_end)`` (``(None, None)``: the plan finishes)."""
        return None, None

    def over(self, tracker: PlanTracker, duration: float) -> bool:
        """Whether the plan tracked by ``tracker`` (``duration`` [s] long) is over."""
        raise NotImplementedError

    def act(self, policy: PlanTrackingPolicy, obs: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The action (4,) float32 of ``policy`` for the observation ``obs`` (its state ``x (14,)``) once the plan is
        over."""
        raise NotImplementedError

    def for_interface(self, interface: EnvInterface) -> AfterPlan:
        """This setting ready to act through ``interface`` (itself unless it builds a policy)."""
        return self

    def spawn(self) -> AfterPlan:
        """An independent copy for a copy of the policy (itself unless it holds memory)."""
        return self

    def reset(self) -> None:
        """Forget the episode."""


class HandOver(AfterPlan):
    """Another policy acts once the tracker has finished (the touchdown after the plan's last flight, or its last
    knot); the plan's last knot acts on the step that ends the plan.

    Args:
        fallback: the policy (None: HS-DDP MPC with default options,
            [`hsddp_gym.planners.policies.mpc.MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy], for the
            tracking policy's interface).
    """

    acts_on_ending_step = False

    def __init__(self, fallback: Policy | None = None) -> None:
        if fallback is not None and not isinstance(fallback, Policy):
            raise TypeError(f"fallback must be a Policy or None, got {type(fallback).__name__}")
        self.fallback = fallback

    def over(self, tracker: PlanTracker, duration: float) -> bool:
        return tracker.finished

    def act(self, policy: PlanTrackingPolicy, obs: np.ndarray, x: np.ndarray) -> np.ndarray:
        return self.fallback.act(obs)

    def for_interface(self, interface: EnvInterface) -> HandOver:
        if self.fallback is not None:
            return self
        from hsddp_gym.planners.policies.mpc import MPCPolicy  # the MPC imports the tracker; imported when needed

        return HandOver(MPCPolicy(interface))

    def spawn(self) -> HandOver:
        return HandOver(self.fallback.spawn())

    def reset(self) -> None:
        self.fallback.reset()

    def __repr__(self) -> str:
        return f"HandOver({type(self.fallback).__name__})"


class HoldPosture(AfterPlan):
    """Once the plan has run out (the tracker finished, or its cursor at the plan's end): the plan's last control
    plus a joint PD to its last knot's joint angles, ``u = U[-1] + kp (q_j,end - q_j) - kd qd_j``.

    Args:
        kp: joint stiffness [N m/rad] ([`HOLD_KP`][HOLD_KP]).
        kd: joint damping [N m s/rad] ([`HOLD_KD`][HOLD_KD]).
    """

    def __init__(self, kp: float = HOLD_KP, kd: float = HOLD_KD) -> None:
        self.kp = check_positive(kp, "kp", allow_zero=True)
        self.kd = check_positive(kd, "kd", allow_zero=True)

    def over(self, tracker: PlanTracker, duration: float) -> bool:
        return tracker.finished or tracker.time >= duration - 1e-9

    def act(self, policy: PlanTrackingPolicy, obs: np.ndarray, x: np.ndarray) -> np.ndarray:
        x_end, u_end = policy.tracker.X[-1], policy.tracker.U[-1]
        return policy.interface.action_from_torque(u_end + self.kp * (x_end[3:NQ] - x[3:NQ]) - self.kd * x[NQ + 3:])

    def __repr__(self) -> str:
        return f"HoldPosture(kp={self.kp!r}, kd={self.kd!r})"


class RepeatCycle(AfterPlan):
    """The plan is never over: the tracker returns to the start of phase ``loop_phase`` when its cursor would enter
    phase ``loop_end`` (None: at the end of the plan), so that the cycle in between repeats
    ([`PlanTracker`][hsddp_gym.planners.policies.tracking.PlanTracker], *Cycle*).

    Args:
        loop_phase: the phase the cursor returns to (its mode that of the phase the cycle ends in).
        loop_end: the phase whose start sends the cursor back (None: the end of the plan).
    """

    def __init__(self, loop_phase: int, loop_end: int | None = None) -> None:
        self.loop_phase = check_int(loop_phase, "loop_phase", minimum=0)
        self.loop_end = None if loop_end is None else check_int(loop_end, "loop_end", minimum=1)

    def loop(self) -> tuple[int | None, int | None]:
        return self.loop_phase, self.loop_end

    def over(self, tracker: PlanTracker, duration: float) -> bool:
        return False

    def __repr__(self) -> str:
        return f"RepeatCycle({self.loop_phase!r}, {self.loop_end!r})"


class PlanTrackingPolicy(Policy):
    """Tracks one HS-DDP plan with its feedback law while the observed contacts decide the phase (module docstring).

    Args:
        solution: the plan, a [`Solution`][hsddp_gym.planners.optimizer.solution.Solution] (its gains for the env's
            control period); the env should start at its ``X[0]`` (e.g. ``options={"state": plan.X[0]}`` at reset).
        touchdown: the tracker's touchdown rule (None: every contact flag counts,
            [`ContactFlags`][hsddp_gym.planners.policies.touchdown.ContactFlags]).
        after_plan: [`HandOver`][HandOver], [`HoldPosture`][HoldPosture] or [`RepeatCycle`][RepeatCycle] (None:
            ``HandOver()``, the MPC).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), solution=None,
                 touchdown: TouchdownRule | None = None, after_plan: AfterPlan | None = None) -> None:
        super().__init__(interface)
        if solution is None:
            raise ValueError("solution must be a Solution (the plan to track)")
        if after_plan is not None and not isinstance(after_plan, AfterPlan):
            raise TypeError(f"after_plan must be a HandOver, HoldPosture or RepeatCycle, got "
                            f"{type(after_plan).__name__}")
        self.solution = solution
        self.touchdown = touchdown
        self.after_plan = (after_plan if after_plan is not None else HandOver()).for_interface(interface)
        self.duration = float(np.sum(solution.schedule.durations))
        """The plan's duration [s]."""
        self.tracker: PlanTracker | None = None
        self.errors: list[float] = []
        """Per control step while tracking: [`tracking_error`][hsddp_gym.planners.policies.tracking.tracking_error] to
        the plan."""
        self.nominal_states: list[np.ndarray] = []
        """Per control step while tracking: the plan's state (14,) at the cursor the action came from."""
        self.reset()

    def _reset_copy_state(self) -> None:
        self.after_plan = self.after_plan.spawn()

    def reset(self) -> None:
        loop_phase, loop_end = self.after_plan.loop()
        self.tracker = PlanTracker.from_solution(self.solution, touchdown=self.touchdown, loop_phase=loop_phase,
                                                 loop_end=loop_end)
        self.errors = []
        self.nominal_states = []
        self.after_plan.reset()

    @property
    def plan_over(self) -> bool:
        """Whether the plan is over (``after_plan`` acts)."""
        return self.after_plan.over(self.tracker, self.duration)

    @property
    def fallback(self) -> Policy | None:
        """The policy that takes over after the plan ([`HandOver`][HandOver]), else None."""
        return getattr(self.after_plan, "fallback", None)

    @property
    def stats(self) -> dict | None:
        """The fallback's planner statistics (replans, failures, solve times), if it has any."""
        return getattr(self.fallback, "stats", None)

    @property
    def last_solution(self):
        """The fallback's latest plan, if it plans."""
        return getattr(self.fallback, "last_solution", None)

    def act(self, obs: np.ndarray) -> np.ndarray:
        x, mode, _ = self._parse(obs)
        if not self.plan_over:
            self.tracker.sync(mode, x)
            if not (self.after_plan.acts_on_ending_step and self.plan_over):
                x_nom, _ = self.tracker.nominal()
                self.errors.append(tracking_error(x, x_nom))
                self.nominal_states.append(x_nom)
                u = self.tracker.control(x)
                self.tracker.advance(self.interface.control_dt)
                return self.interface.action_from_torque(u)
        return self.after_plan.act(self, obs, x)

    def __repr__(self) -> str:
        return (f"PlanTrackingPolicy(touchdown={self.tracker.touchdown!r}, after_plan={self.after_plan!r}, "
                f"phases={self.tracker.n_phases})")


__all__ = ["HOLD_KP", "HOLD_KD", "AfterPlan", "HandOver", "HoldPosture", "RepeatCycle", "PlanTrackingPolicy"]

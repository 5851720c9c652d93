"""The plan tracker's touchdown rules and cycle, and what the plan-tracking policy does when the plan is over: each
test builds the contacts and states that trigger one rule on a small hand-made plan and checks where the cursor
goes or which law acts."""

from __future__ import annotations

import types

import numpy as np
import pytest

from hsddp_gym.core.conventions import NQ, NX, Mode
from hsddp_gym.core.observation import build_observation
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.touchdown import ContactFlags, FootClearance, SeenAirborne
from hsddp_gym.planners.policies.tracking import PlanTracker
from hsddp_gym.planners.policies.tracking_policy import HandOver, HoldPosture, PlanTrackingPolicy, RepeatCycle

DS, FL, FS, BS = Mode.DOUBLE_STANCE, Mode.FLIGHT, Mode.FRONT_STANCE, Mode.BACK_STANCE
KNOTS, DT = 10, 0.01  # each phase 0.1 s


def _tracker(modes, next_mode, **kwargs) -> PlanTracker:
    n = len(modes)
    X, U, K = np.zeros((n * KNOTS + 1, NX)), np.zeros((n * KNOTS, 4)), np.zeros((n * KNOTS, 4, NX))
    return PlanTracker(X, U, K, np.arange(n + 1) * KNOTS, modes, np.full(n, DT), next_mode, **kwargs)


def _in_phase(tracker, phase, local_time=0.0) -> PlanTracker:
    tracker.phase, tracker.local_time = phase, local_time
    return tracker


def _standing(height: float) -> np.ndarray:
    """A level state (14,) whose feet are ``height`` [m] above the ground."""
    x = np.zeros(NX)
    x[1] = height - FootClearance().robot.foot_heights(x[:NQ])[0]
    return x


# ------------------------------------------------------------------------------------------ touchdown rules
def test_contact_flags_take_a_flag_right_after_the_lift_off_for_the_landing():
    tr = _in_phase(_tracker((DS, FL, DS), DS), 1)
    tr.sync(DS)  # both feet still flagged from the push-off
    assert tr.phase == 2 and tr.local_time == 0.0


def test_seen_airborne_counts_a_flag_only_for_a_foot_seen_unflagged_in_the_phase():
    tr = _in_phase(_tracker((DS, FL, DS), DS, touchdown=SeenAirborne()), 1)
    tr.sync(DS)  # flags left over from the push-off
    assert tr.phase == 1
    tr.sync(FS)  # the back foot is seen in the air; the front one, flagged, has not been
    assert tr.phase == 1
    tr.sync(DS)  # the back foot lands
    assert tr.phase == 2


def test_seen_airborne_counts_every_flag_after_the_late_fraction_of_the_phase():
    tr = _in_phase(_tracker((DS, FL, DS), DS, touchdown=SeenAirborne(0.5)), 1, 0.049)
    tr.sync(DS)
    assert tr.phase == 1
    tr.local_time = 0.05  # half the flight's 0.1 s
    tr.sync(DS)
    assert tr.phase == 2


def test_the_evidence_of_a_phase_is_forgotten_in_the_next_one():
    tr = _in_phase(_tracker((DS, FL, DS, FL, DS), DS, touchdown=SeenAirborne()), 1)
    tr.sync(FL)  # both feet seen in the air during the first flight
    _in_phase(tr, 3)  # the second flight, no foot seen in the air yet
    tr.sync(DS)
    assert tr.phase == 3
    tr.sync(FL)
    tr.sync(DS)
    assert tr.phase == 4


def test_foot_clearance_counts_a_flag_only_for_a_foot_seen_that_high_in_the_phase():
    rule = FootClearance(0.02)
    low, high = _standing(0.015), _standing(0.025)
    tr = _in_phase(_tracker((DS, FL, DS), DS, touchdown=rule), 1)
    tr.sync(FL, low)  # in the air but skimming the ground
    tr.sync(DS, low)
    assert tr.phase == 1
    tr.sync(FL)  # no state: no foot seen clear
    tr.sync(DS)
    assert tr.phase == 1
    tr.sync(FL, high)
    assert tr.phase == 1
    tr.sync(DS, low)
    assert tr.phase == 2


def test_the_landing_foot_decides_and_a_stance_foot_is_not_a_touchdown():
    tr = _in_phase(_tracker((BS, FL, FS), FS, touchdown=SeenAirborne()), 1)
    tr.sync(FL)
    tr.sync(BS)  # the back foot again: not the foot the next phase stands on
    assert tr.phase == 1
    tr.sync(FS)
    assert tr.phase == 2


@pytest.mark.parametrize("rule", [ContactFlags(), SeenAirborne(), FootClearance()])
def test_every_rule_waits_for_a_late_touchdown_and_lifts_off_on_time(rule):
    tr = _tracker((DS, FL, DS), DS, touchdown=rule)
    tr.sync(DS, _standing(0.0))
    tr.advance(0.1)  # the stance ends on time
    assert tr.phase == 1 and tr.local_time == 0.0
    tr.advance(0.5)  # far past the flight: waits on its last knot
    assert tr.phase == 1 and tr.knot == 2 * KNOTS - 1


def test_rule_arguments_are_checked():
    with pytest.raises(ValueError, match="late_fraction"):
        SeenAirborne(1.5)
    with pytest.raises(ValueError, match="clearance"):
        FootClearance(0.0)
    with pytest.raises(TypeError, match="touchdown"):
        _tracker((DS, FL), DS, touchdown="clearance")


# ------------------------------------------------------------------------------------------ the cycle
def test_the_touchdown_that_ends_the_plan_returns_the_cursor_to_loop_phase():
    tr = _in_phase(_tracker((DS, FL, DS, FL), DS, loop_phase=2), 3)
    tr.sync(DS)
    assert tr.phase == 2 and tr.loops == 1 and not tr.finished


def test_a_plan_ending_in_stance_returns_to_loop_phase_when_its_time_runs_out():
    tr = _in_phase(_tracker((DS, FL, DS), FL, loop_phase=1), 2)
    tr.advance(0.1)
    assert tr.phase == 1 and tr.local_time == 0.0 and tr.loops == 1 and not tr.finished


def test_loop_end_sends_the_cursor_back_before_the_plan_ends():
    tr = _in_phase(_tracker((DS, FL, DS, FL, DS), DS, loop_phase=0, loop_end=2), 1)
    tr.sync(DS)  # the touchdown that starts phase loop_end
    assert tr.phase == 0 and tr.loops == 1
    with pytest.raises(ValueError, match="loop_phase"):
        _tracker((DS, FL, DS, FL, DS), DS, loop_phase=1, loop_end=2)  # a flight cannot follow the cycle's end
    with pytest.raises(ValueError, match="loop_end"):
        _tracker((DS, FL, DS, FL, DS), DS, loop_phase=2, loop_end=2)


# ------------------------------------------------------------------------------------------ after the plan
class _Constant(Policy):
    def act(self, obs):
        return np.full(4, 0.5, dtype=np.float32)


def _policy(after_plan, modes=(DS, FL), final_mode=DS) -> PlanTrackingPolicy:
    """Two phases of 0.1 s (torques 1 N m, then 2 N m; no feedback; last joint angles 0.1 rad), acting at 100 Hz with a
    torque limit of 10 N m: a (DS, FL) -> DS plan ends at a touchdown, a (FL, DS) -> FL plan when its time runs out."""
    n = 2 * KNOTS
    X, K = np.zeros((n + 1, NX)), np.zeros((n, 4, NX))
    X[-1, 3:NQ] = 0.1
    U = np.r_[np.full((KNOTS, 4), 1.0), np.full((KNOTS, 4), 2.0)]
    schedule = types.SimpleNamespace(modes=modes, durations=np.full(2, KNOTS * DT), final_mode=final_mode)
    plan = types.SimpleNamespace(X=X, U=U, K=K, phase_start=np.array([0, KNOTS, n]), schedule=schedule)
    return PlanTrackingPolicy(EnvInterface(control_dt=DT, torque_limit=10.0), plan, after_plan=after_plan)


def _act(policy, mode: Mode) -> float:
    """The policy's first normalized action for a resting state observed in the contact ``mode``."""
    obs = build_observation(np.zeros(NX), [mode.in_contact(0), mode.in_contact(1)], 0.0, 0.296)
    return float(policy(obs)[0])


def _fly(policy) -> None:
    """Track the (DS, FL) plan to its flight."""
    for _ in range(KNOTS):
        assert _act(policy, DS) == pytest.approx(0.1)
    assert _act(policy, FL) == pytest.approx(0.2) and not policy.plan_over


def test_hand_over_lets_the_plans_last_knot_act_on_the_ending_touchdown_then_the_fallback():
    policy = _policy(HandOver(_Constant()))
    _fly(policy)
    assert _act(policy, DS) == pytest.approx(0.2)  # the touchdown that ends the plan: its last knot once more
    assert policy.plan_over and len(policy.errors) == KNOTS + 2
    assert _act(policy, DS) == pytest.approx(0.5) and len(policy.errors) == KNOTS + 2
    twin = policy.spawn()
    assert twin.fallback is not policy.fallback and not twin.plan_over


def test_hold_posture_acts_on_the_touchdown_that_ends_the_plan():
    policy = _policy(HoldPosture(kp=10.0, kd=1.0))
    _fly(policy)
    # the plan's last control plus the joint PD to its last knot's angles: 2 + 10 (0.1 - 0) - 1 * 0 = 3 N m
    assert _act(policy, DS) == pytest.approx(0.3)
    assert policy.plan_over and len(policy.errors) == KNOTS + 1


def test_hold_posture_acts_once_the_plans_time_has_run_out():
    policy = _policy(HoldPosture(kp=10.0, kd=1.0), modes=(FL, DS), final_mode=FL)
    for _ in range(KNOTS):
        assert _act(policy, FL) == pytest.approx(0.1)
    for _ in range(KNOTS):
        assert _act(policy, DS) == pytest.approx(0.2)
    assert policy.plan_over  # the last step's advance reached the plan's end
    assert _act(policy, DS) == pytest.approx(0.3) and len(policy.errors) == 2 * KNOTS


def test_repeat_cycle_is_never_over():
    policy = _policy(RepeatCycle(0))
    _fly(policy)
    assert _act(policy, DS) == pytest.approx(0.1)  # the touchdown that ends the plan starts the cycle again
    assert policy.tracker.loops == 1 and policy.tracker.phase == 0 and not policy.plan_over


def test_after_plan_must_be_a_setting():
    with pytest.raises(TypeError, match="after_plan"):
        _policy("hold")
    with pytest.raises(TypeError, match="fallback"):
        HandOver("mpc")

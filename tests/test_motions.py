"""HS-DDP motions beyond the bound (hsddp_gym.planners.motions): each motion re-plans with AL + ReB, follows its mode
sequence and meets every limit; feet that land together get one switching-constraint row each; bad arguments are
refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.core.conventions import BACK, FRONT, IVX, NQ, Mode
from hsddp_gym.planners.motions import (
    JOINT_LIMITS,
    SWITCHING_TOLERANCE,
    motion_limits,
    plan_motion,
    plan_pronk,
    plan_transition,
    pronk_problem,
    pronk_reference,
    transition_problem,
)
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.tasks import PlanResult

DS, FL, BS, FS = "DS", "FL", "BS", "FS"


def assert_limits(res: PlanResult) -> None:
    """Every limit, measured on the plan's arrays (not only the summary's verdict)."""
    pr, X, U, GRF = res.problem, res.X, res.U, res.GRF
    assert res.solution.converged, res.summary["status"]
    assert np.all(np.isfinite(X)) and np.all(np.isfinite(U))
    assert np.max(np.abs(U)) <= pr.constraints.torque_limit + 1e-9
    st = pr.stance
    fz, fx = GRF[:, 1::2], GRF[:, 0::2]
    assert np.all(fz[st] >= 0.0)
    assert np.all(np.abs(fx[st]) <= pr.constraints.friction * fz[st] + 1e-9)
    assert np.all(fz[~st] == 0.0)  # no force on a foot in the air
    (h_lo, h_hi), (k_lo, k_hi) = JOINT_LIMITS
    assert h_lo <= X[:, [3, 5]].min() and X[:, [3, 5]].max() <= h_hi
    assert k_lo <= X[:, [4, 6]].min() and X[:, [4, 6]].max() <= k_hi
    robot = pr.dynamics.robot
    g = [robot.foot_heights(res.X_pre[i, :NQ])[f] for i in range(pr.n_phases) for f in pr.schedule.touchdown_feet(i)]
    assert len(g) == sum(len(pr.schedule.touchdown_feet(i)) for i in range(pr.n_phases)) > 0
    assert float(np.sum(np.square(g))) <= SWITCHING_TOLERANCE
    lim = res.summary["limits"]
    assert lim["ok"] and not lim["violated"], lim
    assert lim["touchdowns"] == len(g)


@pytest.mark.parametrize("speed", [0.5, 1.0, 1.5])
def test_the_pronk_replans_at_its_speed_and_meets_every_limit(speed):
    res = plan_pronk(cycles=2, speed=speed)
    assert isinstance(res, PlanResult) and res.method == "al-reb"
    assert res.summary["modes"] == [DS, FL, DS, FL] and res.summary["final_mode"] == DS
    pr = res.problem
    # every flight lands both feet: a switching row for each
    for i in (1, 3):
        assert pr.schedule.touchdown_feet(i) == (FRONT, BACK)
    assert pr.n_switching == pr.n_phases + 2
    assert_limits(res)
    assert abs(res.summary["avg_forward_speed"] - speed) <= 0.1 * speed
    # both feet down together at each flight's end, within the switching tolerance
    for i in (1, 3):
        h = pr.dynamics.robot.foot_heights(res.X_pre[i, :NQ])
        assert np.all(np.abs(h) < 5e-3), h
    assert res.summary["solve_time_s"] > 0 and res.summary["al_iterations"] >= 1


def test_the_pronk_references_put_both_feet_on_the_ground_at_the_neutral_point():
    from hsddp_gym.core.model import CheetahModel

    robot = CheetahModel()
    for event, sign in (("liftoff", -1.0), ("touchdown", 1.0)):
        x = pronk_reference(event, 1.2, (0.1, 0.08))
        q = x[:NQ]
        assert np.allclose(robot.foot_heights(q), 0.0, atol=1e-9)
        offsets = robot.foot_positions(q)[:, 0] - robot.hip_positions(q)[:, 0]
        assert np.allclose(offsets, sign * 1.2 * 0.1 / 2.0, atol=1e-9)
        assert x[IVX] == 1.2 and x[NQ + 1] == pytest.approx(-sign * 9.81 * 0.08 / 2.0)


@pytest.mark.parametrize("motion, modes, final", [
    ("stand_to_bound", [DS, BS, FL, FS, FL], BS),
    ("bound_pronk_bound", [BS, FL, FS, FL, DS, FL, DS, BS, FL, FS, FL], BS),
    ("bound_to_stop", [BS, FL, FS, FL, DS], DS),
])
def test_each_transition_replans_in_its_mode_sequence_and_meets_every_limit(motion, modes, final):
    res = plan_transition(motion, speed=1.0, cycles=1)
    assert res.summary["modes"] == modes and res.summary["final_mode"] == final
    assert [m.short for m in res.problem.schedule.modes] == modes
    assert_limits(res)
    x0 = res.problem.x0
    robot = res.problem.dynamics.robot
    if motion == "stand_to_bound":  # starts at rest on both feet
        assert np.all(x0[NQ:] == 0.0) and np.allclose(robot.foot_heights(x0[:NQ]), 0.0, atol=1e-9)
        assert res.X[-1, IVX] > 0.5
    if motion == "bound_to_stop":  # ends at rest in double stance
        assert np.max(np.abs(res.X[-1, NQ:])) < 0.05
        assert np.allclose(robot.foot_heights(res.X[-1, :NQ]), 0.0, atol=5e-3)
    if motion == "bound_pronk_bound":  # the bound lands both feet into the pronk, which lifts the front foot first
        assert res.problem.schedule.touchdown_feet(3) == (FRONT, BACK)
        assert res.problem.schedule.touchdown_feet(6) == ()


def test_the_limits_check_can_fail():
    res = plan_pronk(cycles=1, speed=1.0)
    pr = res.problem
    base = motion_limits(pr, res.X, res.X_pre, res.U, res.GRF)
    assert base["ok"]
    U = res.U.copy()
    U[10, 2] = 40.0
    assert "torque" in motion_limits(pr, res.X, res.X_pre, U, res.GRF)["violated"]
    GRF = res.GRF.copy()
    GRF[5, 1] = -1.0
    assert "normal_force" in motion_limits(pr, res.X, res.X_pre, res.U, GRF)["violated"]
    GRF = res.GRF.copy()
    GRF[5, 0] = 0.7 * GRF[5, 1]
    assert "friction" in motion_limits(pr, res.X, res.X_pre, res.U, GRF)["violated"]
    X = res.X.copy()
    X[3, 4] = -3.0
    assert "knee_range" in motion_limits(pr, X, res.X_pre, res.U, res.GRF)["violated"]
    X_pre = res.X_pre.copy()
    X_pre[1, 1] += 0.05  # both feet 5 cm up at the landing
    out = motion_limits(pr, res.X, X_pre, res.U, res.GRF)
    assert "switching" in out["violated"] and not out["ok"]


def test_a_simultaneous_touchdown_constrains_both_feet_and_the_bound_keeps_one_row_per_phase():
    from hsddp_gym.planners.optimizer.objective import Objective

    pr, _ = pronk_problem(cycles=1, speed=1.0)
    assert pr.switch_phase.tolist() == [0, 1, 1] and pr.switch_foot.tolist() == [-1, FRONT, BACK]
    X_pre = np.tile(pronk_reference("touchdown", 1.0), (pr.n_phases, 1))
    X_pre[1, 6] += 0.2  # bend the back knee: the back foot only leaves the ground
    g = Objective(pr).switching_values(X_pre)
    assert g[1] == pytest.approx(0.0, abs=1e-9) and abs(g[2]) > 1e-3
    bound = HybridProblem.bounding(2)
    assert bound.n_switching == bound.n_phases
    assert bound.switch_foot.tolist() == bound.touchdown.tolist()


def test_the_transition_schedules_follow_the_cycles():
    pr, phases = transition_problem("bound_pronk_bound", 1.0, cycles=2)
    modes = [m.short for m in pr.schedule.modes]
    assert modes == [BS, FL, FS, FL] * 2 + [DS, FL] * 2 + [DS] + [BS, FL, FS, FL] * 2
    assert [p.gait for p in phases].count("pronk") == 5
    assert pr.schedule.final_mode == Mode.BACK_STANCE


@pytest.mark.parametrize("call, name", [
    (lambda: plan_pronk(speed=2.5), "speed"),
    (lambda: plan_pronk(speed=0.1), "speed"),
    (lambda: plan_pronk(speed=True), "speed"),
    (lambda: plan_pronk(cycles=0), "cycles"),
    (lambda: plan_pronk(durations=(0.1,)), "durations"),
    (lambda: plan_pronk(durations=(0.1, 0.001)), "durations"),
    (lambda: plan_transition("gallop"), "motion"),
    (lambda: plan_transition("stand_to_bound", speed=-1.0), "speed"),
    (lambda: plan_transition("bound_to_stop", cycles=0), "cycles"),
    (lambda: plan_motion("triple_flip"), "motion"),
    (lambda: pronk_reference("apex", 1.0), "event"),
])
def test_bad_arguments_are_refused_by_name(call, name):
    with pytest.raises((ValueError, TypeError), match=name):
        call()


def test_bad_options_are_refused_by_name():
    with pytest.raises(TypeError, match="options"):
        plan_pronk(cycles=1, options="al-reb")

"""Terrain for the planner (hsddp_gym.core.terrain) and the jumps of hsddp_gym.planners.motions: the terrain's heights
and argument checks, flat terrain leaves a problem bit-identical, the switching constraint measures from the terrain,
the gap jump and the box jump re-plan with AL + ReB and meet every limit, the gap landing is beyond the gap, the
backflip's problem asks for a turn of -2 pi, and its plan turns by -2 pi, lands and ends at rest within every limit
(joint ranges, knees and lifted feet above the ground included)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IZ, NGRF, NQ, NU, NX, Mode
from hsddp_gym.core.terrain import GAP_DEPTH, Terrain
from hsddp_gym.planners.motions import (
    BOX_HEIGHT,
    GAP_WIDTH,
    JOINT_LIMITS,
    JUMP_FLIGHT,
    JUMPS,
    MOTIONS,
    backflip_problem,
    jump_problem,
    jump_terrain,
    motion_limits,
    plan_backflip,
    plan_jump,
)
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.objective import ConstraintState, Objective
from hsddp_gym.planners.optimizer.problem import ConstraintSpec, HybridProblem
from hsddp_gym.planners.optimizer.solution import SolverOptions


# ----------------------------------------------------------------------------------------------- terrain
def test_terrain_heights_of_each_profile():
    flat = Terrain.flat()
    assert flat.is_flat and flat.height(-3.0) == 0.0 and flat.height(7.0) == 0.0
    step = Terrain.step(0.5, 0.1)
    assert step.height(0.49) == 0.0 and step.height(0.5) == 0.1 and step.height(2.0) == 0.1  # edges go right
    box = Terrain.box(1.0, 1.5, 0.2)
    np.testing.assert_array_equal(box.heights([0.0, 1.0, 1.2, 1.5, 3.0]), [0.0, 0.2, 0.2, 0.0, 0.0])
    assert not box.over_gap([1.2]).any() and not box.is_flat
    gap = Terrain.gap(0.4, 0.7)
    xs = np.array([[0.39, 0.4], [0.69, 0.7]])
    np.testing.assert_array_equal(gap.over_gap(xs), [[False, True], [True, False]])
    assert gap.heights(xs).shape == (2, 2) and gap.height(0.5) == -GAP_DEPTH and gap.height(0.8) == 0.0
    assert "gap 0.40..0.70 m" in gap.describe() and flat.describe() == "flat"
    with pytest.raises(dataclasses_frozen_error()):
        gap.edges = ()


def dataclasses_frozen_error():
    import dataclasses

    return dataclasses.FrozenInstanceError


@pytest.mark.parametrize("make, name", [
    (lambda: Terrain.step(float("nan"), 0.1), "x0"),
    (lambda: Terrain.step(0.0, "high"), "height"),
    (lambda: Terrain.box(1.0, 0.5, 0.1), "x1"),
    (lambda: Terrain.box(0.0, 1.0, -0.1), "height"),
    (lambda: Terrain.gap(0.0, 0.3, depth=0.0), "depth"),
    (lambda: Terrain.gap(True, 0.3), "x0"),
    (lambda: Terrain((0.5, 0.2), (0.0, 0.1, 0.0), (False,) * 3), "edges"),
    (lambda: Terrain((0.5,), (0.0,), (False,)), "levels"),
    (lambda: Terrain((0.5,), (0.0, 0.1), (False,)), "gaps"),
    (lambda: Terrain.flat().height(float("inf")), "x"),
])
def test_terrain_refuses_bad_arguments_by_name(make, name):
    with pytest.raises(ValueError, match=rf"\b{name}\b"):
        make()


def test_a_problem_refuses_a_terrain_that_is_not_one():
    base = HybridProblem.bounding(cycles=1)
    with pytest.raises(TypeError, match="terrain"):
        HybridProblem(base.dynamics, base.schedule, base.costs, base.x0, base.constraints, terrain="flat")


# ----------------------------------------------------------------------------------------------- flat is bit-identical
def test_flat_terrain_leaves_a_bounding_problem_bit_identical():
    base = HybridProblem.bounding(cycles=2)
    flat = HybridProblem(base.dynamics, base.schedule, base.costs, base.x0, base.constraints, terrain=Terrain.flat())
    from hsddp_gym.planners.tasks import heuristic_warm_start

    U0 = heuristic_warm_start(base).U
    opts = SolverOptions(max_al_iterations=2)
    a, b = HSDDP(opts).solve(base, U0), HSDDP(opts).solve(flat, U0)
    for name in ("X", "X_pre", "U", "K", "switching", "multipliers"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.objective == b.objective


def test_the_switching_constraint_measures_from_the_terrain_under_the_foot():
    base = HybridProblem.bounding(cycles=1)
    robot = base.dynamics.robot
    X_pre = np.tile(base.x0, (base.n_phases, 1))
    feet = robot.foot_positions(base.x0[:NQ])
    raised = Terrain.step(float(min(feet[:, 0])) - 1.0, 0.07)  # both feet over the step
    on = HybridProblem(base.dynamics, base.schedule, base.costs, base.x0, base.constraints, terrain=raised)
    g_flat, g_step = Objective(base).switching_values(X_pre), Objective(on).switching_values(X_pre)
    rows = base.switch_foot >= 0
    np.testing.assert_allclose(g_step[rows], g_flat[rows] - 0.07, rtol=0, atol=1e-15)
    # the constraint's gradient is the foot height's (piecewise-constant terrain): a finite-difference check
    i, foot = int(base.switch_phase[rows][0]), int(base.switch_foot[rows][0])
    q = base.x0[:NQ].copy()
    eps = 1e-7
    for j in range(NQ):
        dq = np.zeros(NQ)
        dq[j] = eps
        fd = (robot.foot_positions(q + dq)[foot, 1] - robot.foot_positions(q - dq)[foot, 1]) / (2 * eps)
        assert robot.foot_height_derivatives(q, foot)[1][j] == pytest.approx(fd, abs=1e-6)
    assert i >= 0


def test_a_ground_at_one_level_is_measured_as_a_terrain_would_measure_it():
    """A flat ground raised by ``dz`` takes the flat problems' path (``g = foot_z - dz``): the same switching values and
    augmented-Lagrangian derivatives, bit for bit, as the terrain path of a profile that has that level under the
    feet (and another far away)."""
    base = HybridProblem.bounding(cycles=1)
    X_pre = np.tile(base.x0, (base.n_phases, 1))
    X_pre[:, IZ] += np.linspace(-0.02, 0.03, base.n_phases)
    dz = -0.0137
    level, stepped = Terrain.flat().raised(dz), Terrain.step(100.0, 0.5).raised(dz)
    assert level.uniform_height == dz and stepped.uniform_height is None
    problems = [HybridProblem(base.dynamics, base.schedule, base.costs, base.x0, base.constraints, terrain=t)
                for t in (level, stepped)]
    objectives = [Objective(p) for p in problems]
    g = [o.switching_values(X_pre) for o in objectives]
    rows = base.switch_foot >= 0
    assert np.array_equal(g[0], g[1]) and np.any(g[0][rows] != Objective(base).switching_values(X_pre)[rows])
    cs = ConstraintState(sigma=5.0, lam=np.linspace(-1.0, 1.0, base.n_switching), use_al=True, use_reb=False,
                         delta_torque=0.1, delta_grf=0.1, eps_torque=0.01, eps_grf=0.01)
    N, n = base.n_knots, base.n_phases
    X, U, GRF = np.tile(base.x0, (N + 1, 1)), np.zeros((N, NU)), np.zeros((N, NGRF))
    Phi = []
    for o in objectives:
        out = [np.zeros(s) for s in ((N, NX), (N, NU), (N, NX, NX), (N, NU, NU), (N, NU, NX), (n, NX), (n, NX, NX))]
        o.derivatives(X, X_pre, U, GRF, np.zeros((N, NGRF, NX)), np.zeros((N, NGRF, NU)), cs, *out)
        Phi.append(out[5:])
    assert np.array_equal(Phi[0][0], Phi[1][0]) and np.array_equal(Phi[0][1], Phi[1][1])
    assert np.any(Phi[0][0] != 0.0)


def test_the_bounding_problem_raises_its_references_by_the_ground_of_each_phase():
    base = HybridProblem.bounding(cycles=1)
    ground = np.linspace(0.01, -0.03, base.n_phases)
    on = HybridProblem.bounding(cycles=1, ground=ground, terrain=Terrain.flat().raised(0.01))
    for a, b, z in zip(base.costs, on.costs, ground):
        assert b.x_ref[IZ] == a.x_ref[IZ] + z and b.x_final[IZ] == a.x_final[IZ] + z
        assert np.array_equal(np.delete(b.x_ref, IZ), np.delete(a.x_ref, IZ))
    assert on.terrain.uniform_height == 0.01 and base.terrain is None
    with pytest.raises(ValueError, match="ground"):
        HybridProblem.bounding(cycles=1, ground=ground[:-1])
    with pytest.raises(ValueError, match="ground"):
        HybridProblem.bounding(cycles=1, ground=np.full(base.n_phases, np.nan))


# ----------------------------------------------------------------------------------------------- jumps
def test_the_motions_list_the_jumps():
    assert set(JUMPS) <= set(MOTIONS) and "backflip" in MOTIONS
    with pytest.raises(ValueError, match="motion"):
        jump_problem("long_jump")


@pytest.fixture(scope="module", params=JUMPS)
def jump(request):
    return plan_jump(request.param, speed=1.0, cycles=1)


def test_each_jump_replans_and_meets_every_limit(jump):
    pr, U, GRF = jump.problem, jump.U, jump.GRF
    assert jump.solution.converged, jump.summary["status"]
    assert np.max(np.abs(U)) <= pr.constraints.torque_limit + 1e-9
    st = pr.stance
    fz, fx = GRF[:, 1::2], GRF[:, 0::2]
    assert np.all(fz[st] >= 0.0) and np.all(np.abs(fx[st]) <= pr.constraints.friction * fz[st] + 1e-9)
    lim = jump.summary["limits"]
    assert lim["ok"] and not lim["violated"], lim
    assert {"stance_knots_over_gap", "min_terrain_clearance", "landing_feet_x"} <= set(lim)
    # the switching constraint on the terrain: every landing foot at the terrain's height under it
    robot = pr.dynamics.robot
    g = []
    for i, f in zip(pr.switch_phase, pr.switch_foot):
        if f >= 0:
            p = robot.foot_positions(jump.X_pre[i, :NQ])[f]
            g.append(p[1] - pr.terrain.height(p[0]))
    assert float(np.sum(np.square(g))) <= 1e-4
    # the jump's flight is the long one, and the schedule is the bound's around it
    assert pr.schedule.durations.max() == pytest.approx(JUMP_FLIGHT)
    assert jump.summary["modes"][:4] == ["BS", "FL", "FS", "FL"] and jump.summary["final_mode"] == "BS"
    assert 0.8 <= jump.summary["avg_forward_speed"] <= 1.2


def _stance_feet_x(res, foot):
    pr = res.problem
    feet = np.array([pr.dynamics.robot.foot_positions(res.X[k, :NQ])[foot, 0] for k in range(pr.n_knots)])
    return feet[pr.stance[:, foot]]


def test_the_gap_landing_is_beyond_the_gap(jump):
    if jump.summary["motion"] != "gap_jump":
        pytest.skip("the box jump has no gap")
    near, far = jump.problem.terrain.edges
    assert far - near == pytest.approx(GAP_WIDTH)
    for foot in (FRONT, BACK):
        xs = _stance_feet_x(jump, foot)
        assert not np.any((xs >= near) & (xs < far)), foot  # never standing over the gap
        assert xs.min() < near and xs.max() > far  # before it, then beyond it
    # the first landing of each foot after the jump's flight is beyond the far edge, with a margin
    pr = jump.problem
    robot = pr.dynamics.robot
    i = int(np.argmax(pr.schedule.durations))  # the jump's flight: the front foot lands at its end
    assert robot.foot_positions(jump.X_pre[i, :NQ])[FRONT, 0] > far + 0.02
    assert robot.foot_positions(jump.X_pre[i + 2, :NQ])[BACK, 0] > far + 0.02
    # and the limits would catch a foot over the gap: the same plan on a gap that covers its landings fails
    moved = Terrain.gap(far - 0.05, far + 0.5)
    other = HybridProblem(pr.dynamics, pr.schedule, pr.costs, pr.x0, pr.constraints, terrain=moved)
    bad = motion_limits(other, jump.X, jump.X_pre, jump.U, jump.GRF)
    assert not bad["ok"] and "gap" in bad["violated"] and bad["stance_knots_over_gap"] > 0


def test_the_box_jump_ends_bounding_on_the_box(jump):
    if jump.summary["motion"] != "box_jump":
        pytest.skip("the gap jump has no box")
    pr = jump.problem
    edge = pr.terrain.edges[0]
    assert pr.terrain.height(edge + 0.1) == BOX_HEIGHT
    robot = pr.dynamics.robot
    last = [robot.foot_positions(jump.X_pre[i, :NQ])[f] for i, f in zip(pr.switch_phase, pr.switch_foot) if f >= 0]
    for p in last[-2:]:  # the last landings: on the box, at its height
        assert p[0] > edge and p[1] == pytest.approx(BOX_HEIGHT, abs=0.01)
    assert jump.X[-1, 1] > 0.1 + 0.2  # the trunk above the box
    # a foot through the box's side is caught: the same plan with the box moved under the swinging feet
    higher = Terrain.box(edge - 0.3, edge + 3.0, 0.3)
    other = HybridProblem(pr.dynamics, pr.schedule, pr.costs, pr.x0, pr.constraints, terrain=higher)
    assert "terrain_clearance" in motion_limits(other, jump.X, jump.X_pre, jump.U, jump.GRF)["violated"]


def test_jump_terrain_sits_between_the_take_off_and_the_landings():
    t = jump_terrain("gap_jump", 1.0, 2)
    assert t.over_gap(t.edges[0] + 0.01) and t.edges[1] - t.edges[0] == pytest.approx(GAP_WIDTH)
    b = jump_terrain("box_jump", 1.0, 2)
    assert b.height(b.edges[0]) == BOX_HEIGHT
    with pytest.raises(ValueError, match="speed"):
        jump_terrain("gap_jump", 3.0)


# ----------------------------------------------------------------------------------------------- backflip
def test_the_backflips_problem_asks_for_a_turn_of_minus_two_pi():
    pr, phases = backflip_problem()
    assert [m.short for m in pr.schedule.modes] == ["DS", "BS", "FL", "DS"]
    assert pr.schedule.final_mode == Mode.DOUBLE_STANCE
    assert pr.schedule.touchdown_feet(2) == (FRONT, BACK)  # the flight lands both feet
    assert pr.x0[IPITCH] == 0.0 and np.all(pr.x0[NQ:] == 0.0)  # from standing at rest
    assert pr.XF[2, IPITCH] == pytest.approx(-2 * math.pi) and pr.XF[3, IPITCH] == pytest.approx(-2 * math.pi)
    assert pr.XF[1, NQ + IPITCH] < 0  # nose-up rotation at take-off (negative pitch is nose-up)
    # the landing reference is the standing posture a whole turn on: the feet on the ground
    assert np.allclose(pr.dynamics.robot.foot_heights(pr.XF[3, :NQ]), 0.0, atol=1e-9)


@pytest.fixture(scope="module")
def backflip():
    return plan_backflip()


def test_the_backflip_turns_over_and_meets_every_limit(backflip):
    pr, X, U, GRF = backflip.problem, backflip.X, backflip.U, backflip.GRF
    assert backflip.solution.converged, backflip.summary["status"]
    lim = backflip.summary["limits"]
    assert lim["ok"] and not lim["violated"], lim
    # torque, normal force, friction cone on the returned plan
    assert np.max(np.abs(U)) <= pr.constraints.torque_limit + 1e-9
    st = pr.stance
    fz, fx = GRF[:, 1::2], GRF[:, 0::2]
    assert np.all(fz[st] >= 0.0) and np.all(np.abs(fx[st]) <= pr.constraints.friction * fz[st] + 1e-9)
    # the stated joint ranges, both legs, every knot; knees above the ground, lifted feet not below it
    (h_lo, h_hi), (k_lo, k_hi) = JOINT_LIMITS
    assert h_lo <= X[:, [3, 5]].min() and X[:, [3, 5]].max() <= h_hi
    assert k_lo <= X[:, [4, 6]].min() and X[:, [4, 6]].max() <= k_hi
    assert lim["min_knee_height"] >= 0.0 and lim["min_swing_foot_height"] >= -0.01
    # both feet land together (sum g^2 within the paper's stop rule)
    assert lim["switching_violation"] <= 1e-4 and lim["touchdowns"] == 2
    # the turn: through -2 pi in flight (monotonically nose-up from the push to the landing), at rest at the end
    start = backflip.solution.phase_start
    pitch = X[:, IPITCH]
    assert pitch[start[2]] > -math.pi / 2 and pitch[start[3]] < -1.75 * math.pi  # take-off, touchdown
    assert np.all(np.diff(pitch[start[1]:start[3] + 1]) < 0)
    assert pitch[-1] == pytest.approx(-2 * math.pi, abs=0.05)
    assert np.max(np.abs(X[-1, NQ:])) < 0.2
    assert backflip.summary["final_mode"] == "DS"


def test_joint_and_clearance_terms_are_off_by_default_and_penalize_only_outside():
    assert ConstraintSpec().joint_limits is None and ConstraintSpec().knee_clearance is None
    pr, _ = backflip_problem()
    assert pr.constraints.joint_limits == JOINT_LIMITS and pr.constraints.knee_clearance > 0
    obj = Objective(pr)
    n = pr.n_knots
    X = np.tile(pr.XF[3], (n + 1, 1))  # standing at -2 pi: inside every range, knees high, feet on the ground
    d, _ = obj._clearance_deficit(X)
    assert np.all(obj._joint_excess(X) == 0.0) and np.all(d[:, :2] == 0.0)
    # a foot on the ground is short of the lifted feet's clearance only where its leg is not in stance
    assert np.all(d[:, 2:][pr.stance] == 0.0) and np.all(d[:, 2:][~pr.stance] < 0.0)
    X[:, 5] = JOINT_LIMITS[0][1] + 0.2  # a back hip beyond its range
    assert np.all(obj._joint_excess(X)[:, 2] > 0.2)
    with pytest.raises(ValueError, match="joint_limits"):
        ConstraintSpec(joint_limits=((0.0, 0.1), (-1.0, 0.0)))

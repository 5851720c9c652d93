"""The MPC of a planned motion (planners/policies/mpc/motion.py): what remains of the motion as a problem, the flight's
timing from the ballistic centre of mass, the planner's held laws and barriers, the multipliers of simultaneous
touchdowns carried by the warm start, and the policy in the backflip env."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401  (registers the envs)
from hsddp_gym.core.conventions import NQ, NX, Mode
from hsddp_gym.planners.motions.references import motion_mpc_policy, motion_reference
from hsddp_gym.planners.optimizer.hold import held_input_gains
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.mpc import MotionOptions, MPCOptions, MPCPolicy
from hsddp_gym.planners.policies.mpc.motion import (
    GRF_RELAXATION,
    MotionMPCPolicy,
    MotionReference,
    com_state,
    flight_time_to_go,
    held_knots,
    reference_knots,
    remaining_problem,
)
from hsddp_gym.planners.policies.mpc.warm_start import shift_plan
from hsddp_gym.planners.policies.touchdown import FootClearance
from hsddp_gym.planners.policies.tracking import PlanTracker
from hsddp_gym.registry import TASKS
from hsddp_gym.rollout.policies import PolicySpec, make_policy, task_policy_spec

DT = MPCOptions().plan.planner_dt
FLIGHT = 2  # the backflip's phases: push (double stance), take-off (back stance), flight, landing (double stance)
LANDING = 3


FRICTION = MPCOptions().plan.friction


@pytest.fixture(scope="module")
def reference() -> MotionReference:
    return motion_reference("backflip", DT, 2, FRICTION)


@pytest.fixture(scope="module")
def interface() -> EnvInterface:
    env = gym.make("hsddp_gym/Backflip-v0")
    out = EnvInterface.from_env(env)
    env.close()
    return out


# ---------------------------------------------------------------------------------------------- the reference
def test_reference_flips_and_lands_on_both_feet(reference):
    sol, pb = reference.solution, reference.problem
    assert sol.converged
    assert sol.X[-1, 2] == pytest.approx(-2.0 * np.pi, abs=0.1)
    # the flight ends in a touchdown of both feet: two switching-constraint rows in its phase
    assert list(pb.switch_phase).count(FLIGHT) == 2
    assert np.isfinite(reference.touchdown_com_height[FLIGHT])
    assert np.isnan(reference.touchdown_com_height[[0, 1, LANDING]]).all()


def test_flight_time_to_go_is_the_ballistic_time_left_of_the_reference_flight(reference):
    """Over the reference's own flight, the time left predicted from the centre of mass is the time the plan has
    left, to the discretization (the centre of mass of a robot in flight is ballistic; the plan's semi-implicit Euler
    steps put it lower by about ``g h T / 2``, a few knots of time)."""
    pb, sol = reference.problem, reference.solution
    robot = pb.dynamics.robot
    a, b = int(pb.phase_start[FLIGHT]), int(pb.phase_start[FLIGHT + 1])
    z_td = float(reference.touchdown_com_height[FLIGHT])
    for k in range(a, b, 16):
        z, vz = com_state(robot, sol.X[k])
        left = flight_time_to_go(z, vz, z_td, robot.params.gravity)
        assert left == pytest.approx((b - k) * pb.dt, abs=3 * pb.dt)


def test_flight_time_to_go_cases():
    g = 9.81
    assert flight_time_to_go(1.0, 0.0, 1.0, g) == pytest.approx(0.0)
    assert flight_time_to_go(1.0, 2.0, 1.0, g) == pytest.approx(2 * 2.0 / g)  # up and back down
    assert flight_time_to_go(0.5, 0.1, 1.0, g) == 0.0  # below the touchdown height, cannot rise to it
    assert flight_time_to_go(1.0, -1.0, 0.5, g) == pytest.approx((-1.0 + np.sqrt(1.0 + 2 * g * 0.5)) / g)
    with pytest.raises(ValueError, match="vz"):
        flight_time_to_go(1.0, float("nan"), 0.5, g)
    with pytest.raises(ValueError, match="gravity"):
        flight_time_to_go(1.0, 0.0, 0.5, 0.0)


def test_com_state_checks_the_state(reference):
    with pytest.raises(ValueError, match="x"):
        com_state(reference.problem.dynamics.robot, np.zeros(NQ))


# ---------------------------------------------------------------------------------------------- what remains
def test_remaining_problem_keeps_the_phases_left_and_their_references(reference):
    ref = reference.problem
    x = reference.solution.X[int(ref.phase_start[1]) + 8].copy()
    pb = remaining_problem(reference, 1, 0.07, x, last_duration=0.4, elapsed=0.03)
    assert [m.name for m in pb.schedule.modes] == [m.name for m in ref.schedule.modes[1:]]
    assert pb.schedule.final_mode == ref.schedule.final_mode
    assert pb.schedule.durations[0] == pytest.approx(0.07)
    assert pb.schedule.durations[-1] == pytest.approx(0.4)
    assert pb.schedule.durations[1] == pytest.approx(ref.schedule.durations[FLIGHT])
    assert pb.knots.tolist() == [28, int(ref.knots[FLIGHT]), 160]
    np.testing.assert_array_equal(pb.x0, x)
    # the running references are the reference's trajectory at the same point of the motion: 30 ms into the
    # take-off for the first knot, the flight's first knot for the flight's
    first, take_off = reference.solution.X[int(ref.phase_start[1]) + 12], reference.solution.X[int(ref.phase_start[2])]
    np.testing.assert_array_equal(pb.XR[0, 1:], first[1:])
    np.testing.assert_array_equal(pb.XR[pb.phase_start[1], 1:], take_off[1:])
    assert pb.XR[0, 0] == pytest.approx(x[0])  # the trunk x of the references is moved to the state's
    assert pb.XR[pb.phase_start[1], 0] - pb.XR[0, 0] == pytest.approx(take_off[0] - first[0])
    np.testing.assert_array_equal(pb.YR[0], reference.solution.GRF[int(ref.phase_start[1]) + 12])
    # the terminal references stay the phases' own
    np.testing.assert_array_equal(pb.XF, ref.XF[1:])


def test_a_retimed_flight_follows_the_reference_flight_by_its_fraction(reference):
    ref = reference.problem
    n_flight = int(ref.knots[FLIGHT])
    x = reference.solution.X[int(ref.phase_start[FLIGHT])]
    T = float(ref.schedule.durations[FLIGHT])
    half = remaining_problem(reference, FLIGHT, 0.25 * T, x, elapsed=0.5 * T)  # half gone, half the rest left
    idx = reference_knots(reference, FLIGHT, 0.5 * T, half)
    a = int(ref.phase_start[FLIGHT])
    flight = idx[:half.phase_start[1]]
    assert flight[0] == a + n_flight // 2
    assert flight[-1] >= a + n_flight - 3 and flight[-1] < a + n_flight
    assert np.all(np.diff(flight) >= 1)  # twice as fast: the reference's knots at every other knot or more
    # the last phase beyond its nominal end holds the reference's last knot
    longer = remaining_problem(reference, LANDING, 0.5, reference.solution.X[-1], elapsed=0.1)
    tail = reference_knots(reference, LANDING, 0.1, longer)
    assert tail[-1] == reference.problem.n_knots - 1
    assert tail[0] == int(ref.phase_start[LANDING]) + 40


@pytest.mark.parametrize("kwargs, match", [({"phase": 4}, "phase"), ({"duration": 0.0}, "duration"),
                                           ({"last_duration": -1.0}, "last_duration")])
def test_remaining_problem_rejects_bad_arguments(reference, kwargs, match):
    args = {"phase": 1, "duration": 0.05, "x": reference.problem.x0, "last_duration": None}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        remaining_problem(reference, **args)


# ---------------------------------------------------------------------------------------------- the warm start
def test_the_warm_start_keeps_the_multipliers_of_each_landing_foot(reference):
    """The flight lands both feet: its two switching-constraint rows keep their own multipliers when the reference
    is shifted onto what remains of the motion from the take-off."""
    ref, sol = reference.problem, reference.solution
    lam = np.arange(1.0, ref.n_switching + 1.0)  # a distinct value per row
    tracker = reference.tracker(1, 0.0)
    pb = remaining_problem(reference, 1, float(ref.schedule.durations[1]), sol.X[int(ref.phase_start[1])])
    U, X, K, out = shift_plan(pb, pb.x0, tracker, sol, lam, ref)
    assert out.shape == (pb.n_switching,)
    for r, (j, f) in enumerate(zip(pb.switch_phase, pb.switch_foot)):
        source = [i for i, (p, g) in enumerate(zip(ref.switch_phase, ref.switch_foot)) if p == j + 1 and g == f]
        assert out[r] == lam[source[0]]
    np.testing.assert_array_equal(U, sol.U[int(ref.phase_start[1]):])


def test_carry_evidence_keeps_a_foot_seen_clear_in_the_same_phase(reference):
    old = reference.tracker(FLIGHT, 0.1, touchdown=FootClearance())
    x = reference.solution.X[int(reference.problem.phase_start[FLIGHT]) + 40]
    old.sync(Mode.FLIGHT, x)
    assert old._seen == [True, True]
    new = reference.tracker(0, 0.0, touchdown=FootClearance())
    new.carry_evidence(old)
    assert new._seen == [True, True]
    old.phase = LANDING  # a cursor that has moved on: its evidence is of another phase
    newer = reference.tracker(0, 0.0, touchdown=FootClearance())
    newer.carry_evidence(old)
    assert newer._seen == [False, False]


# ---------------------------------------------------------------------------------------------- the policy
@pytest.fixture
def policy(interface) -> MotionMPCPolicy:
    return motion_mpc_policy(interface, "backflip")


def test_the_plans_act_with_held_laws_and_the_references_barriers(policy, reference):
    assert policy.hold == 2 and policy.planner.hold == 2
    c = policy.reference.constraint_state
    assert c.delta_grf < GRF_RELAXATION
    assert policy.planner.barrier == (c.delta_torque, GRF_RELAXATION, c.eps_torque, c.eps_grf)
    assert policy.reference.problem.constraints.friction == FRICTION  # the plans' friction margin
    assert policy.law.pushing.friction == FRICTION
    x = reference.solution.X[int(reference.problem.phase_start[1]) + 4].copy()
    policy.phase, policy._phase_time = 1, 4 * DT
    policy.law.plan.tracker.phase, policy.law.plan.tracker.local_time = 1, 4 * DT
    assert policy.replan(x)
    plan = policy.law.plan
    np.testing.assert_array_equal(plan.tracker.K, held_input_gains(policy.planner._solver, plan.problem, 2))
    assert not np.array_equal(plan.tracker.K, plan.solution.K)  # the warm starts keep the per-knot gains


def test_a_stance_plan_starts_with_its_feet_still(policy, reference):
    """Planned from a landing whose feet still move, a double stance starts from the state after the touchdown's
    impact (its feet held from the first knot), not from one whose held feet would drift."""
    x = reference.solution.X_pre[FLIGHT].copy()
    x[NQ + 3:] += np.array([2.0, -3.0, 1.5, 2.5])  # the legs swing on
    robot = policy.robot
    assert np.abs(robot.foot_velocities(x)).max() > 0.3
    policy.phase, policy._phase_time = LANDING, 0.0
    policy.law.plan = dataclasses.replace(policy.law.plan, tracker=reference.tracker(LANDING, 0.0, law=True))
    assert policy.replan(x)
    x0 = policy.law.plan.problem.x0
    np.testing.assert_allclose(robot.foot_velocities(x0), 0.0, atol=1e-9)
    np.testing.assert_array_equal(x0[:NQ], x[:NQ])


def test_the_tracker_waits_only_at_a_touchdown_past_its_phase(reference):
    flight = float(reference.problem.schedule.durations[FLIGHT])
    tracker = reference.tracker(FLIGHT, flight - 0.01)
    assert not tracker.waiting
    tracker.advance(0.02)  # past the flight's end, no touchdown seen: the cursor waits on the flight's last knot
    assert tracker.waiting and tracker.phase == FLIGHT
    tracker.sync(Mode.DOUBLE_STANCE, None)  # the landing (both feet: the late fraction counts them)
    assert tracker.phase == LANDING and not tracker.waiting
    push = reference.tracker(1, 0.0)  # the take-off ends in a lift-off: the cursor moves on by time
    push.advance(float(reference.problem.schedule.durations[1]) + 0.01)
    assert push.phase == FLIGHT and not push.waiting


def test_a_late_landing_is_replanned_at_every_control_step():
    """A flight whose feet have not landed at its nominal end is re-planned from every state until they do: the law
    does not hold the plan's last knot before the touchdown (the feet hovering above the ground)."""
    env = gym.make("hsddp_gym/Backflip-v0")
    options = MPCOptions().replace(replan_feedback=None)  # no feedback re-plans: re-plans by the period and phases
    policy = make_policy(PolicySpec("mpc", options, env_id="hsddp_gym/Backflip-v0"), env)
    ref = policy.reference
    flight = float(ref.problem.schedule.durations[FLIGHT])
    x = ref.solution.X[int(ref.problem.phase_start[LANDING]) - 2].copy()
    x[1] += 0.03  # 3 cm higher than the reference at the flight's end: the feet land late
    obs, _ = env.reset(seed=0, options={"state": x})
    policy.reset()
    policy.phase, policy._phase_time, policy._tracker_phase, policy._since_replan = FLIGHT, flight - 0.004, FLIGHT, 0.0
    policy.law.plan = dataclasses.replace(policy.law.plan, tracker=ref.tracker(FLIGHT, flight - 0.004,
                                                                               policy.touchdown, law=True))
    replans, waited = [policy.stats["replans"]], []
    for _ in range(6):
        obs, _, terminated, _, info = env.step(policy.act(obs))
        replans.append(policy.stats["replans"])
        waited.append(policy.law.plan.tracker.waiting)
        if policy.phase != FLIGHT:
            break
    assert policy.phase == LANDING and waited[0], "the test's flight must be late"
    # a cursor that waits after a step is re-planned at the next (the period alone: once in 4 steps)
    assert all(replans[k + 2] > replans[k + 1] for k in range(len(waited) - 1) if waited[k])


def test_no_landing_is_counted_early_in_a_flight(policy):
    flight = float(policy.reference.problem.schedule.durations[FLIGHT])
    policy.phase = FLIGHT
    policy._phase_time = 0.2 * flight
    assert policy._in_early_flight()
    policy._phase_time = 0.5 * flight
    assert not policy._in_early_flight()
    policy.phase = LANDING
    policy._phase_time = 0.0
    assert not policy._in_early_flight()


def test_online_timing_is_an_mpc_option(interface):
    assert MPCOptions().motion.retime is False  # fixed timing by default
    options = MPCOptions().replace(retime=True)
    assert options.motion == MotionOptions(retime=True)
    assert motion_mpc_policy(interface, "backflip", options).motion_options.retime is True
    assert MPCOptions.from_record({"motion": {"retime": True}}) == options


def test_policy_rejects_bad_arguments(interface, reference):
    with pytest.raises(ValueError, match="name"):
        motion_mpc_policy(interface, "cartwheel")
    with pytest.raises(ValueError, match="planner_dt"):
        motion_mpc_policy(interface, "backflip", MPCOptions().replace(planner_dt=0.003))
    with pytest.raises(ValueError, match="planner_dt"):
        held_knots(0.005, 0.002)
    assert held_knots(0.005, 0.00125) == 4
    with pytest.raises(TypeError, match="options"):
        motion_mpc_policy(interface, "backflip", {"retime": False})
    with pytest.raises(TypeError, match="reference"):
        MotionMPCPolicy(interface, "backflip")
    with pytest.raises(ValueError, match="grid"):  # a reference of another grid
        MotionMPCPolicy(interface, reference, MPCOptions().replace(planner_dt=0.00125))
    with pytest.raises(TypeError, match="retime"):
        MotionOptions(retime="no")
    with pytest.raises(ValueError, match="max_flight_stretch"):
        MotionOptions(max_flight_stretch=0.5)


def _actions(env, policy, steps: int, seed: int) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    policy.reset()
    out = []
    for _ in range(steps):
        a = policy.act(obs)
        out.append(a)
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    return np.array(out)


def test_the_policy_is_deterministic(policy):
    env = gym.make("hsddp_gym/Backflip-v0")
    a = _actions(env, policy, 30, 3)
    b = _actions(env, policy, 30, 3)
    np.testing.assert_array_equal(a, b)
    assert policy.stats["replans"] >= 30 // 4
    env.close()


def test_the_mpc_flips_from_the_plans_start():
    """From the reference's start (no reset noise), the MPC turns the robot over and lands it on its feet."""
    env = gym.make("hsddp_gym/Backflip-v0", reset_noise_scale=0.0)
    policy = make_policy("mpc", env)
    obs, _ = env.reset(seed=0)
    policy.reset()
    info = {}
    while True:
        obs, _, term, trunc, info = env.step(policy.act(obs))
        if term or trunc:
            break
    assert info["success"], info
    assert policy.stats["planner_failures"] == 0
    assert policy.stats["phase_replans"] == 3  # take-off, flight, landing
    env.close()


def test_the_backflip_tasks_mpc_is_the_motion_mpc():
    env = gym.make("hsddp_gym/Backflip-v0")
    policy = make_policy("mpc", env)
    assert isinstance(policy, MotionMPCPolicy) and policy.motion == "backflip"
    assert policy.reference is motion_reference("backflip", DT, 2, FRICTION)  # solved once per process
    spec = task_policy_spec("mpc", "hsddp_gym/Backflip-v0")
    assert spec.env_id == "hsddp_gym/Backflip-v0"
    described = spec.describe()
    assert described["class"].endswith("MotionMPCPolicy") and described["motion"] == "backflip"
    assert not isinstance(make_policy(PolicySpec("mpc"), gym.make("hsddp_gym/Bounding-v0")), MotionMPCPolicy)
    env.close()


def test_shapes_of_the_reference(reference):
    assert reference.solution.X.shape == (reference.problem.n_knots + 1, NX)
    assert reference.law.K.shape == reference.solution.K.shape
    assert isinstance(reference.tracker(0, 0.0), PlanTracker)


def test_a_dataset_of_the_backflip_mpc_records_it(tmp_path):
    from hsddp_gym.datasets.generation import generate_dataset

    result = generate_dataset("mpc", 1, tmp_path / "flip", seed=58400, env_id="hsddp_gym/Backflip-v0",
                              max_episode_steps=40, progress=False)
    meta = result.metadata
    assert result.total_steps == 40
    assert meta["policy"]["class"] == "hsddp_gym.planners.policies.mpc.motion.MotionMPCPolicy"
    assert meta["policy"]["motion"] == "backflip"
    assert meta["policy"]["options"]["motion"]["retime"] is False


# ---------------------------------------------------------------------------------------------- bound to stop
def test_a_reference_whose_heuristic_rollout_diverges_starts_from_the_1ms_plan(monkeypatch):
    """On the plans' 2.5 ms grid the bound's heuristic rollout diverges (too stiff for explicit steps): the reference
    of bound-to-stop starts from the transition solved on the 1 ms grid, sampled onto the plans' knots with its
    feedback law, and converges."""
    from hsddp_gym.core.dynamics import HybridDynamics
    from hsddp_gym.planners.motions import references
    from hsddp_gym.planners.motions.problems import motion_warm_start
    from hsddp_gym.planners.tasks import WarmStartDivergedError

    problem, phases = references.MOTION_PROBLEMS["bound_to_stop"][0](HybridDynamics(dt=DT, integrator="semi_implicit"))
    with pytest.raises(WarmStartDivergedError):
        motion_warm_start(problem, phases)
    calls = []
    original = references._fine_guess
    monkeypatch.setattr(references, "_fine_guess", lambda *a: calls.append(1) or original(*a))
    references._reference.cache_clear()
    ref = motion_reference("bound_to_stop", DT, 2, FRICTION, cycles=2)
    assert calls == [1]
    assert ref.solution.converged
    assert ref.problem.schedule.final_mode == Mode.DOUBLE_STANCE
    assert np.abs(ref.solution.X[-1, NQ:]).max() < 0.3  # it ends at rest


def test_the_bound_to_stop_tasks_mpc_is_the_motion_mpc():
    env = gym.make("hsddp_gym/BoundToStop-v0")
    policy = make_policy("mpc", env)
    assert isinstance(policy, MotionMPCPolicy) and policy.motion == "bound_to_stop"
    assert policy.reference is motion_reference("bound_to_stop", DT, 2, FRICTION, cycles=2)
    assert policy.gait is None and policy.reference.hand_over is None  # it ends standing, held
    env.close()


@pytest.mark.parametrize("env_id, motion, hand_over", [("hsddp_gym/StandToBound-v0", "stand_to_bound", 5),
                                                       ("hsddp_gym/BoundPronkBound-v0", "bound_pronk_bound", 13)])
def test_the_transitions_into_a_bound_are_handed_to_the_bounding_mpc(env_id, motion, hand_over):
    """A transition into a bound is re-planned until its first steady bounding cycle, then the bounding MPC acts,
    with the same state estimator (its action history and filter carry over) and one statistics dict."""
    env = gym.make(env_id)
    policy = make_policy("mpc", env)
    assert isinstance(policy, MotionMPCPolicy) and policy.motion == motion
    assert policy.reference.hand_over == hand_over and isinstance(policy.gait, MPCPolicy)
    assert policy.gait.estimator is policy.estimator
    obs, _ = env.reset(seed=0)
    policy.reset()
    gait_replans, motion_replans, sent = None, None, None
    for _ in range(env.spec.max_episode_steps):
        was = policy.handed_over
        action = policy.act(obs)
        if policy.handed_over and not was:  # the step that reached the hand-over phase: the motion still acted
            assert policy.phase == hand_over
            motion_replans, sent = policy.stats["replans"], action.copy()
        elif was and gait_replans is None:  # the gait's first step: it predicts with the motion's last action
            assert policy.gait.last_prediction is not None
            gait_replans = policy.stats["replans"]
            assert np.array_equal(policy.estimator.sent[-2], sent)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert motion_replans is not None and info["success"]
    assert policy.stats is policy.gait.stats is policy.gait.planner.stats
    assert policy.stats["replans"] > gait_replans >= motion_replans  # the bounding MPC re-planned into the same dict
    policy.reset()  # a new episode starts with the motion again
    assert not policy.handed_over and policy.phase == 0 and policy.gait.estimator is policy.estimator
    env.close()


@pytest.fixture(scope="module")
def gap_jump() -> MotionReference:
    return motion_reference("gap_jump", DT, 2, FRICTION)


def test_a_jump_is_planned_where_its_terrain_is(gap_jump):
    """On a terrain the motion is tied to the world: what remains of it keeps the reference's trunk x (the take-off
    before the gap's rim wherever the state is), where on flat ground the references move with the state."""
    ref = gap_jump.problem
    assert ref.terrain is not None and ref.terrain.gaps[1]
    k = int(ref.phase_start[8]) + 4  # in the take-off's back stance
    x = gap_jump.solution.X[k].copy()
    x[0] -= 0.05  # 5 cm short of where the reference is
    pb = remaining_problem(gap_jump, 8, 0.07, x, elapsed=4 * DT)
    assert pb.terrain is ref.terrain
    np.testing.assert_array_equal(pb.XR[:, 0], gap_jump.solution.X[reference_knots(gap_jump, 8, 4 * DT, pb), 0])


@pytest.mark.parametrize("env_id", ["hsddp_gym/GapJump-v0", "hsddp_gym/BoxJump-v0"])
def test_the_jumps_mpc_knows_the_terrain_and_hands_over_after_the_landing(env_id):
    env = gym.make(env_id)
    policy = make_policy("mpc", env)
    assert isinstance(policy, MotionMPCPolicy) and policy.motion == env.unwrapped.task
    terrain = policy.reference.problem.terrain
    assert terrain == env.unwrapped.terrain  # the env puts the terrain where the plan has it
    assert policy.reference.hand_over == 12  # the first bounding cycle after the jump
    env.reset(seed=0)
    policy.reset()
    assert policy.estimator.terrain is terrain and policy.gait.terrain is terrain  # world x by odometry, both
    assert policy.law.ground.terrain is terrain
    env.close()


def test_a_hand_over_must_start_a_bounding_cycle(reference):
    with pytest.raises(ValueError, match="hand_over must be a back stance"):
        dataclasses.replace(reference, hand_over=LANDING)  # the backflip's landing is a double stance
    with pytest.raises(ValueError, match="hand_over"):
        dataclasses.replace(reference, hand_over=0)


def test_dagger_relabels_with_the_motion_mpc(tmp_path, capsys):
    """In a task whose ``mpc`` re-plans its motion, DAgger takes that MPC as its labelling expert (elsewhere in a
    task the plan tracker is the only expert)."""
    pytest.importorskip("torch")
    import json

    from hsddp_gym import cli

    out = tmp_path / "dagger"
    assert cli.main(["train", "--algo", "dagger", "--env", "hsddp_gym/Backflip-v0", "--expert", "mpc", "--rounds", "1",
                     "--episodes-per-round", "1", "--rollout-steps", "20", "--epochs", "1", "--hidden", "16,16",
                     "--eval-episodes", "0", "--quiet", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["expert"]["class"].endswith("MotionMPCPolicy") and summary["expert"]["motion"] == "backflip"
    assert summary["expert_labels"] > 0
    assert cli.main(["train", "--algo", "dagger", "--env", "hsddp_gym/Backflip-v0", "--expert", "heuristic",
                     "--out", str(tmp_path / "x")]) == 2
    assert "or mpc (its MPC)" in capsys.readouterr().err


def test_the_mpc_benchmark_measures_a_tasks_mpc_beside_the_bounds(tmp_path, experiment, capsys):
    """``bench_mpc.py --env``: the task's MPC and the bound's in one run, each re-plan's knots counted."""
    from hsddp_gym.reports.store import read_record

    bench = experiment("bench_mpc")
    record = tmp_path / "speed" / "task_mpc.json"
    assert bench.main(["--env", "hsddp_gym/StandToBound-v0", "--seconds", "0.05", "--record", str(record)]) == 0
    data = read_record(record).data
    assert data["reference"] == "hsddp_gym/Bounding-v0"
    row = data["envs"]["hsddp_gym/StandToBound-v0"]
    assert row["policy"] == "MotionMPCPolicy" and row["replans"] >= 2 and row["seconds"] == pytest.approx(0.05)
    assert row["knots_mean"] > data["envs"]["hsddp_gym/Bounding-v0"]["knots_mean"]  # the whole motion left to plan
    assert data["envs"]["hsddp_gym/Bounding-v0"]["per_knot_ratio_to_bound"] == 1.0
    assert "StandToBound-v0" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        bench.main(["--env", "hsddp_gym/NoSuchEnv-v0"])
    assert "unknown env" in capsys.readouterr().err


# ------------------------------------------------------------------------------------ the ground, periodic gaits
def test_what_remains_is_planned_on_the_measured_ground(reference):
    """A calibrated height bias lowers (or raises) the plans' ground and their trunk references with it."""
    ref = reference.problem
    x = reference.solution.X[int(ref.phase_start[FLIGHT]) + 10]
    flat = remaining_problem(reference, FLIGHT, 0.2, x)
    low = remaining_problem(reference, FLIGHT, 0.2, x, ground=-0.02)
    assert flat.terrain is None
    assert low.terrain.support_heights(np.array([0.0, 0.5]))[0] == pytest.approx(-0.02)
    np.testing.assert_allclose(low.XR[:, 1], flat.XR[:, 1] - 0.02)
    np.testing.assert_array_equal(np.delete(low.XR, 1, axis=1), np.delete(flat.XR, 1, axis=1))
    with pytest.raises(ValueError, match="ground must be finite"):
        remaining_problem(reference, FLIGHT, 0.2, x, ground=np.nan)


def test_feet_are_seen_clear_of_the_measured_ground(reference):
    rule = FootClearance(0.005)
    x = reference.solution.X[int(reference.problem.phase_start[FLIGHT]) - 1]  # the take-off: the back foot down
    assert rule.evidence(Mode.BACK_STANCE, x)[1] is False
    rule.ground = -0.01  # the measurement reads the trunk 1 cm low: a foot at z = 0 is 1 cm above the ground
    assert rule.evidence(Mode.BACK_STANCE, x)[1] is True
    with pytest.raises(ValueError, match="ground must be a finite height"):
        rule.ground = np.nan


@pytest.fixture(scope="module")
def pronk() -> MotionReference:
    return motion_reference("pronk", DT, 2, FRICTION, cycles=4, speed=1.0)


def test_a_periodic_gait_goes_on_at_its_loop_phase(pronk):
    assert pronk.loop_phase == 2 and pronk.hand_over is None
    assert pronk.problem.schedule.modes[2] == pronk.problem.schedule.final_mode == Mode.DOUBLE_STANCE
    with pytest.raises(ValueError, match="loop_phase must be a phase of the mode"):
        dataclasses.replace(pronk, loop_phase=1)  # a flight: the last flight lands in a double stance
    with pytest.raises(ValueError, match="not both"):
        dataclasses.replace(pronk, hand_over=2)


def test_the_pronks_mpc_loops_at_the_touchdown_that_ends_its_reference():
    env = gym.make("hsddp_gym/Pronking-v0", target_speed=1.2)
    policy = make_policy("mpc", env)
    assert isinstance(policy, MotionMPCPolicy) and policy.motion == "pronk"
    assert policy.reference.solution.X[0, NQ] == pytest.approx(1.2)  # planned at the env's target speed
    last = policy.reference.n_phases - 1
    obs, _ = env.reset(seed=0)
    policy.reset()
    phases = []
    for _ in range(300):  # 1.5 s: the reference's 4 cycles are 0.69 s
        obs, _, terminated, _, info = env.step(policy.act(obs))
        assert not terminated
        phases.append(policy.phase)
    wraps = [k for k in range(1, len(phases)) if phases[k - 1] == last and phases[k] == policy.reference.loop_phase]
    assert len(wraps) >= 2 and max(phases) == last  # it went round twice, and never past the reference's end
    assert info["x_velocity"] == pytest.approx(1.2, abs=0.3)
    env.close()


def test_a_late_flights_landing_foot_at_the_ground_has_landed(policy, reference):
    """From a flight's nominal end on, a landing foot within ``touchdown_height`` of the measured ground counts as down
    (a stiff contact bounces it off within a control step, and no flag reports the touchdown)."""
    flight = float(reference.problem.schedule.durations[FLIGHT])
    tracker = reference.tracker(FLIGHT, flight, policy.touchdown)
    tracker.advance(0.005)
    assert tracker.waiting
    x = reference.solution.X_pre[FLIGHT].copy()  # both feet at the ground: the reference's touchdown
    assert policy._late_landing(Mode.FLIGHT, x, tracker) == Mode.DOUBLE_STANCE
    high = x.copy()
    high[1] += 0.03  # 3 cm above it: still in the air
    assert policy._late_landing(Mode.FLIGHT, high, tracker) == Mode.FLIGHT
    policy.estimator.model_ground = lambda: 0.03  # the measurement puts the ground 3 cm higher
    assert policy._late_landing(Mode.FLIGHT, high, tracker) == Mode.DOUBLE_STANCE
    off = motion_mpc_policy(policy.interface, "backflip", MPCOptions().replace(touchdown_height=None))
    assert off._late_landing(Mode.FLIGHT, x, tracker) == Mode.FLIGHT  # the rule off: the flags alone


def test_the_push_failures_experiment_reports_each_push(tmp_path, experiment, capsys):
    """``push_failures.py``: the push drawn, the outcome, the state at the push and the best plan's violation."""
    import json

    script = experiment("push_failures")
    out = tmp_path / "pushes.json"
    assert script.main(["--env", "hsddp_gym/StandToBound-v0", "--first-seed", "3", "--seeds", "1", "--window", "0.1",
                        "--out", str(out)]) == 0
    row = json.loads(out.read_text())["rows"][0]
    lo, hi = TASKS["stand_to_bound"].push_window
    assert row["seed"] == 3 and lo <= row["push_time"] <= hi and len(row["delta_v"]) == 3
    assert row["at_push"]["phase"] >= 0 and row["plans_after_push"] >= 1 and row["best_switching_violation"] >= 0.0
    assert "StandToBound-v0" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        script.main(["--env", "hsddp_gym/Bounding-v0"])  # no motion MPC

"""Mode schedules, the hybrid rollout, the heuristic bounding warm start, and determinism."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IX, IZ, NGRF, NU, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics, Linearization
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.core.rollout import Trajectory, knot_layout, rollout
from hsddp_gym.core.schedule import BOUNDING_CYCLE, PAPER_BOUNDING_DURATIONS, ModeSchedule
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController

BS, FL, FS, DS = Mode.BACK_STANCE, Mode.FLIGHT, Mode.FRONT_STANCE, Mode.DOUBLE_STANCE


def heuristic_rollout(dyn: HybridDynamics, cycles: int = 5, **kwargs) -> Trajectory:
    schedule = ModeSchedule.bounding(cycles)
    controller = HeuristicBoundingController(dyn.robot).as_schedule_controller(schedule)
    return rollout(dyn, schedule, paper_initial_state(), controller=controller, **kwargs)


@pytest.fixture(scope="module")
def bounding_traj() -> Trajectory:
    """The heuristic 5-cycle bounding rollout from the paper's initial state (paper settings)."""
    return heuristic_rollout(HybridDynamics())


# ----------------------------------------------------------------------------------------- ModeSchedule
def test_bounding_factory_follows_the_paper():
    s = ModeSchedule.bounding(5)
    assert len(s) == 20
    assert s.modes == (BS, FL, FS, FL) * 5
    assert s.modes[:4] == BOUNDING_CYCLE
    assert s.final_mode == BS
    np.testing.assert_array_equal(s.durations, np.tile([0.080, 0.072, 0.072, 0.072], 5))
    assert PAPER_BOUNDING_DURATIONS == (0.080, 0.072, 0.072, 0.072)
    knots = s.knots(1e-3)
    np.testing.assert_array_equal(knots, np.tile([80, 72, 72, 72], 5))
    assert knots.dtype.kind == "i"
    assert int(knots.sum()) == 1480
    assert s.total_time == pytest.approx(1.48)
    assert "BS:80.0ms" in repr(s) and repr(s).endswith("-> BS)")


def test_knots_are_rounded_durations():
    s = ModeSchedule([BS, FL, FS], [0.0804, 0.0716, 0.1])
    np.testing.assert_array_equal(s.knots(1e-3), [80, 72, 100])
    np.testing.assert_array_equal(s.knots(2e-3), [40, 36, 50])
    np.testing.assert_array_equal(s.knots(0.0101), np.rint(np.array([0.0804, 0.0716, 0.1]) / 0.0101))
    with pytest.raises(ValueError, match="dt"):
        s.knots(0.2)  # a phase shorter than half a step would get 0 steps


def test_bounding_starting_in_front_stance_and_per_phase_durations():
    s = ModeSchedule.bounding(2, start=FS)
    assert s.modes == (FS, FL, BS, FL) * 2 and s.final_mode == FS
    durations = np.linspace(0.05, 0.12, 8)
    s = ModeSchedule.bounding(2, durations=durations)
    np.testing.assert_array_equal(s.durations, durations)


def test_touchdown_feet_and_next_mode():
    s = ModeSchedule.bounding(2)
    expected = [(), (FRONT,), (), (BACK,)] * 2
    assert [s.touchdown_feet(i) for i in range(len(s))] == expected
    assert [s.bounding_touchdown_foot(i) for i in range(len(s))] == [None, FRONT, None, BACK] * 2
    assert [s.next_mode(i) for i in range(len(s))] == [FL, FS, FL, BS, FL, FS, FL, BS]
    # no switch after the last phase when final_mode defaults to the last mode
    single = ModeSchedule([FL, DS], [0.1, 0.1])
    assert single.final_mode == DS and single.touchdown_feet(0) == (FRONT, BACK) and single.touchdown_feet(1) == ()
    assert ModeSchedule([DS, FS], [0.1, 0.1]).touchdown_feet(0) == ()  # lift-off of the back foot


def test_with_durations_and_equality():
    s = ModeSchedule.bounding(1)
    t = s.with_durations([0.07, 0.06, 0.07, 0.06])
    assert t.modes == s.modes and t.final_mode == s.final_mode
    np.testing.assert_array_equal(t.durations, [0.07, 0.06, 0.07, 0.06])
    np.testing.assert_array_equal(s.durations, PAPER_BOUNDING_DURATIONS)  # the original is unchanged
    assert s == ModeSchedule.bounding(1)
    assert s == ModeSchedule([2, 0, 1, 0], PAPER_BOUNDING_DURATIONS, final_mode=2)  # ints are modes
    assert s != t
    assert s != ModeSchedule(s.modes, s.durations, final_mode=FS)
    assert s != ModeSchedule.bounding(2)
    assert s != "not a schedule"
    assert s.with_durations(s.durations) == s
    with pytest.raises(ValueError, match="durations"):
        s.with_durations([0.1, 0.1])


def test_durations_are_read_only():
    s = ModeSchedule.bounding(1)
    with pytest.raises(ValueError):
        s.durations[0] = 1.0


# ----------------------------------------------------------------------------------------- rollout
def test_trajectory_layout(bounding_traj):
    t = bounding_traj
    assert t.X.shape == (1481, NX) and t.U.shape == (1480, NU) and t.GRF.shape == (1480, NGRF)
    assert t.X_pre.shape == (20, NX) and t.impulses.shape == (20, NGRF)
    assert t.phase_start.tolist() == list(np.concatenate([[0], np.cumsum(np.tile([80, 72, 72, 72], 5))]))
    modes, phase_of_knot, phase_start = knot_layout(t.schedule, t.dt)
    np.testing.assert_array_equal(t.modes, modes)
    np.testing.assert_array_equal(t.phase_of_knot, phase_of_knot)
    np.testing.assert_array_equal(t.phase_start, phase_start)
    for i, mode in enumerate(t.schedule.modes):
        assert np.all(t.modes[t.phase_start[i]:t.phase_start[i + 1]] == int(mode))
        assert np.all(t.phase_of_knot[t.phase_start[i]:t.phase_start[i + 1]] == i)
    np.testing.assert_allclose(t.times, 1e-3 * np.arange(1481))
    assert t.is_finite


def test_open_loop_controls_reproduce_stepwise_dynamics_and_resets(bounding_traj):
    """Replaying the heuristic's torques open loop, and re-deriving every state with the public step and
    reset map, both give the same trajectory bit for bit."""
    dyn = HybridDynamics()
    replay = rollout(dyn, bounding_traj.schedule, bounding_traj.X[0], controls=bounding_traj.U)
    for name in ("X", "X_pre", "U", "GRF", "impulses"):
        np.testing.assert_array_equal(getattr(replay, name), getattr(bounding_traj, name), err_msg=name)

    ref = HybridDynamics()
    schedule = replay.schedule
    x = replay.X[0]
    for i in range(len(schedule)):
        for k in range(replay.phase_start[i], replay.phase_start[i + 1]):
            np.testing.assert_array_equal(replay.X[k], x, err_msg=f"state {k}")
            x, grf = ref.step(x, replay.U[k], schedule.modes[i])
            np.testing.assert_array_equal(replay.GRF[k], grf, err_msg=f"grf {k}")
        np.testing.assert_array_equal(replay.X_pre[i], x, err_msg=f"X_pre {i}")
        if i + 1 < len(schedule):
            x, impulse = ref.reset_map(x, schedule.next_mode(i))
            np.testing.assert_array_equal(replay.impulses[i], impulse, err_msg=f"impulse {i}")
    np.testing.assert_array_equal(replay.X[-1], x)  # no reset after the last phase by default


def test_x_pre_holds_the_pre_reset_states(bounding_traj):
    t = bounding_traj
    dyn = HybridDynamics()
    for i in range(len(t.schedule) - 1):
        start = t.phase_start[i + 1]
        after = t.schedule.next_mode(i)
        if after == Mode.FLIGHT:  # lift-off: nothing jumps
            np.testing.assert_array_equal(t.X[start], t.X_pre[i])
            np.testing.assert_array_equal(t.impulses[i], 0.0)
        else:  # touchdown: the velocity jumps, the configuration does not
            np.testing.assert_array_equal(t.X[start], dyn.reset_map(t.X_pre[i], after)[0])
            np.testing.assert_array_equal(t.X[start, :7], t.X_pre[i, :7])
            assert np.max(np.abs(t.X[start, 7:] - t.X_pre[i, 7:])) > 1e-3
            (foot,) = t.schedule.touchdown_feet(i)
            assert t.impulses[i, 2 * foot + 1] > 0.0
    np.testing.assert_array_equal(t.X[-1], t.X_pre[-1])


def test_final_reset_and_restitution_are_applied(bounding_traj):
    dyn = HybridDynamics()
    schedule, U = bounding_traj.schedule, bounding_traj.U
    t = rollout(dyn, schedule, bounding_traj.X[0], controls=U, apply_final_reset=True)
    np.testing.assert_array_equal(t.X_pre[-1], bounding_traj.X_pre[-1])
    np.testing.assert_array_equal(t.X[-1], dyn.reset_map(t.X_pre[-1], schedule.final_mode)[0])
    bouncy = rollout(dyn, schedule, bounding_traj.X[0], controls=U, restitution=0.5)
    first_touchdown = bounding_traj.phase_start[2]  # end of phase 1 (flight -> front stance)
    np.testing.assert_array_equal(bouncy.X[:first_touchdown], bounding_traj.X[:first_touchdown])
    np.testing.assert_array_equal(bouncy.X_pre[1], bounding_traj.X_pre[1])
    np.testing.assert_array_equal(bouncy.X[first_touchdown], dyn.reset_map(bouncy.X_pre[1], FS, 0.5)[0])
    assert not np.array_equal(bouncy.X[first_touchdown], bounding_traj.X[first_touchdown])


def test_controller_arguments_and_output_shape():
    dyn = HybridDynamics()
    schedule = ModeSchedule([BS, FL], [0.003, 0.002])
    calls = []

    def controller(x, mode, phase, k):
        calls.append((mode, phase, k))
        assert x.shape == (NX,)
        return [0.0, 0.0, 0.0, 0.0]  # any array-like of shape (4,)

    rollout(dyn, schedule, paper_initial_state(), controller=controller)
    assert calls == [(BS, 0, 0), (BS, 0, 1), (BS, 0, 2), (FL, 1, 3), (FL, 1, 4)]
    for bad in (np.zeros(3), np.zeros((4, 1)), np.zeros(5), 0.0):
        with pytest.raises(ValueError, match="controller"):
            rollout(dyn, schedule, paper_initial_state(), controller=lambda x, m, i, k, bad=bad: bad)


def test_rollout_stops_at_the_first_non_finite_state():
    dyn = HybridDynamics()
    schedule = ModeSchedule([BS], [0.02])

    def controller(x, mode, phase, k):
        return np.full(NU, np.nan) if k == 5 else np.zeros(NU)

    t = rollout(dyn, schedule, paper_initial_state(), controller=controller)
    assert not t.is_finite
    assert np.all(np.isfinite(t.X[:6])) and not np.all(np.isfinite(t.X[6]))  # Euler: X[6] has finite q, NaN v
    assert np.all(np.isnan(t.X[7:])) and np.all(np.isnan(t.U[6:]))


# ----------------------------------------------------------------------------------------- heuristic
def test_heuristic_bounding_stays_up_and_moves_forward(bounding_traj):
    t = bounding_traj
    assert t.is_finite
    assert np.min(t.X[:, IZ]) > 0.1
    assert np.max(np.abs(t.X[:, IPITCH])) < 0.6
    speed = (t.X[-1, IX] - t.X[0, IX]) / t.times[-1]
    assert speed > 0.5
    # the body never touches the ground: both ends of the trunk (the hips) and both knees stay well up
    robot = HybridDynamics().robot
    points = np.array([robot.link_points(x[:7]) for x in t.X])  # (N+1, 2 feet, [hip, knee, foot, trunk], 2)
    assert np.min(points[:, :, 0, 1]) > 0.1  # hips (the trunk is 0.10 m tall: its corners are 5 cm off these)
    assert np.min(points[:, :, 1, 1]) > 0.03  # knees
    # it bounds: every cycle moves forward, not one lunge
    cycle_starts = t.phase_start[::4]
    assert np.all(np.diff(t.X[cycle_starts, IX]) > 0.1)
    # the scheduled stance feet actually carry load (f_z > 0 on most stance knots)
    for mode, foot in ((BS, BACK), (FS, FRONT)):
        fz = t.GRF[t.modes == int(mode), 2 * foot + 1]
        assert np.mean(fz > 0.0) > 0.9


# ----------------------------------------------------------------------------------------- determinism
def test_identical_rollouts_are_bit_identical(bounding_traj):
    same_object = HybridDynamics()
    first = heuristic_rollout(same_object)
    second = heuristic_rollout(same_object)
    for t in (first, second):
        for name in ("X", "X_pre", "U", "GRF", "impulses", "modes", "phase_of_knot", "phase_start"):
            np.testing.assert_array_equal(getattr(t, name), getattr(bounding_traj, name), err_msg=name)


def test_linearize_is_deterministic(bounding_traj):
    t = bounding_traj
    n = t.U.shape[0]
    results = []
    for dyn in (HybridDynamics(), HybridDynamics()):
        lin = Linearization(n)
        dyn.linearize(t.X, t.U, t.modes, lin)
        dyn.linearize(t.X, t.U, t.modes, lin)  # twice on the same object
        results.append(lin)
    for name in ("f_x", "f_u", "grf", "grf_x", "grf_u"):
        np.testing.assert_array_equal(getattr(results[0], name), getattr(results[1], name), err_msg=name)


# ----------------------------------------------------------------------------------------- the CLI
# Paper eqs. 32-33 with the weights of original_code_facts §3.5 (MH@0b6ca76), written out here independently of
# planners/optimizer/problem.py: state order [x, z, pitch, hf, kf, hb, kb, dx, dz, dpitch, dhf, dkf, dhb, dkb].
_Q_PAPER = 0.01 * np.array([0, 10, 5, 2, 2, 2, 2, 8, 1, 0.01, 5, 5, 5, 5])
_QF_PAPER = {BS: 100.0 * np.array([0, 20, 8, 3, 3, 3, 3, 10, 2, 0.01, 5, 5, 0.01, 0.01]),
             FL: 100.0 * np.array([0, 20, 8, 3, 3, 3, 3, 10, 2, 0.01, 5, 5, 5, 5]),
             FS: 100.0 * np.array([0, 20, 8, 3, 3, 3, 3, 10, 2, 0.01, 0.01, 0.01, 5, 5])}
_R_PAPER = {BS: np.array([5.0, 5, 1, 1]), FL: np.ones(4), FS: np.array([1.0, 1, 5, 5])}
_S_PAPER = {BS: np.array([0, 0, 0.3, 0.3]), FL: np.zeros(4), FS: np.array([0.15, 0.15, 0, 0])}


def _paper_cost(schedule: ModeSchedule, X, X_pre, U, GRF, dt: float = 1e-3) -> float:
    """sum_k h [(x-xr)'Q(x-xr) + u'Ru + (y-yd)'S(y-yd)] + sum_i 1/2 (x_i^- - xf_i)'Qf_i(x_i^- - xf_i), with
    x_r = x_f = the mode's reference posture (§3.4, v_d = 1 m/s) and y_d = body weight on each stance foot."""
    from hsddp_gym.core.references import end_of_mode_reference

    weight = 8.252 * 9.81
    y_ref = np.array([0.0, weight, 0.0, weight])
    total = 0.0
    k = 0
    for i, (mode, n) in enumerate(zip(schedule.modes, schedule.knots(dt))):
        x_ref = end_of_mode_reference(mode, schedule.bounding_touchdown_foot(i), 1.0)
        for _ in range(n):
            dx, dy = X[k] - x_ref, GRF[k] - y_ref
            total += dt * (dx @ (_Q_PAPER * dx) + U[k] @ (_R_PAPER[mode] * U[k]) + dy @ (_S_PAPER[mode] * dy))
            k += 1
        df = X_pre[i] - x_ref
        total += 0.5 * df @ (_QF_PAPER[mode] * df)
    return float(total)


def test_cli_plan_heuristic_writes_the_summary_and_the_plot(tmp_path, bounding_traj):
    """``hsddp-gym plan --method heuristic --cycles 5 --out DIR``: summary.json with the issue's keys, the numbers
    of the heuristic rollout, the paper's cost, and a plot of the motion."""
    import importlib.metadata
    import json

    from hsddp_gym import cli
    from hsddp_gym.util.io import read_npz

    out = tmp_path / "plan"
    assert cli.main(["plan", "--method", "heuristic", "--cycles", "5", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("avg_forward_speed", "min_body_height", "max_abs_pitch", "touchdown_foot_heights", "cost"):
        assert key in summary, key
    assert summary["command"] == f"hsddp-gym plan --method heuristic --cycles 5 --out {out}"  # not pytest's argv
    t = bounding_traj
    assert summary["avg_forward_speed"] == pytest.approx((t.X[-1, IX] - t.X[0, IX]) / 1.48, rel=1e-12)
    assert summary["min_body_height"] == pytest.approx(np.min(t.X[:, IZ]), rel=1e-12)
    assert summary["max_abs_pitch"] == pytest.approx(np.max(np.abs(t.X[:, IPITCH])), rel=1e-12)
    robot = HybridDynamics().robot
    expected_td = [robot.foot_heights(t.X_pre[i, :7])[t.schedule.touchdown_feet(i)[0]]
                   for i in range(len(t.schedule)) if t.schedule.touchdown_feet(i)]
    assert isinstance(summary["touchdown_foot_heights"], list) and len(expected_td) == 10
    np.testing.assert_allclose(summary["touchdown_foot_heights"], expected_td, rtol=0, atol=1e-12)
    # the cost is the task cost of the written trajectory (its weights: test_summary_cost_uses_the_section_3_5_weights)
    from hsddp_gym.planners.optimizer.metrics import task_cost
    from hsddp_gym.planners.optimizer.problem import HybridProblem

    assert isinstance(summary["cost"], float) and np.isfinite(summary["cost"]) and summary["cost"] > 0.0
    assert summary["cost"] == pytest.approx(task_cost(HybridProblem.bounding(5), t.X, t.X_pre, t.U, t.GRF), rel=1e-12)
    # the written trajectory is the rollout, and the plot of the motion exists and is a PNG
    data = read_npz(out / "trajectory.npz")
    np.testing.assert_array_equal(data["X"], t.X)
    motion = out / summary["files"]["motion"]
    assert motion.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]  # atomic writes leave no temp files
    scripts = {ep.name: ep.value for ep in importlib.metadata.entry_points(group="console_scripts")}
    assert scripts.get("hsddp-gym") == "hsddp_gym.cli:main"  # the console script is installed


def test_summary_cost_uses_the_section_3_5_weights(bounding_traj):
    """``cost`` is the paper's eq. 32-33 cost with the weights of §3.5, recomputed here independently."""
    from hsddp_gym.planners.tasks import plan_bounding

    t = bounding_traj
    summary = plan_bounding("heuristic", cycles=5).summary
    assert summary["cost"] == pytest.approx(_paper_cost(t.schedule, t.X, t.X_pre, t.U, t.GRF), rel=1e-9)


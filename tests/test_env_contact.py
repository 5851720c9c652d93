"""The contact LCP solver and the state-based contact simulator (envs/contact.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hsddp_gym.core.conventions import BACK, FOOT_JOINTS, FOOT_U, FRONT, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.envs.contact import SEPARATE, SLIDE_NEG, SLIDE_POS, STICK, ContactSimulator, solve_contact_lcp

MU = 0.6


@pytest.fixture(scope="module")
def robot():
    return CheetahModel()


def standing_state(robot, lift: float = 0.0, pitch: float = 0.0) -> np.ndarray:
    """Hips at 0.25 pi, knees at -0.5 pi (feet about under the hips), lowest foot ``lift`` above ground."""
    q = np.array([0.0, 0.0, pitch, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])
    q[1] = -robot.foot_heights(q).min() + lift
    return np.concatenate([q, np.zeros(7)])


def pd_hold(sim, q_ref, kp=100.0, kd=1.0, foot_damping=100.0):
    """Hold the joint posture ``q_ref[3:]``: a joint PD (kd * h / I < 1 keeps the light swinging legs stable
    at 1 kHz) plus, for each foot on the ground, a hip-foot damper ``-c J^T J qdot`` that damps the trunk."""
    u = kp * (q_ref[3:] - sim.q[3:]) - kd * sim.v[3:]
    for foot in (FRONT, BACK):
        if sim.contact[foot]:
            joints = list(FOOT_JOINTS[foot])
            J = sim.robot.foot_jacobian(sim.q, foot)[:, joints]
            u[list(FOOT_U[foot])] -= foot_damping * J.T @ (J @ sim.v[joints])
    return u


def check_lcp_solution(G, c, lam, mu, tol=1e-8):
    """Assert the complementarity conditions of a planar Coulomb contact LCP solution."""
    w = G @ lam + c
    for i in range(len(c) // 2):
        ln, lt, wn, wt = lam[2 * i], lam[2 * i + 1], w[2 * i], w[2 * i + 1]
        assert ln >= -tol
        assert wn >= -tol
        assert abs(ln * wn) <= tol
        assert abs(lt) <= mu * ln + tol
        if abs(wt) > 1e-7:  # sliding: friction at the cone edge, opposing the slip
            assert lt == pytest.approx(-np.sign(wt) * mu * ln, abs=tol)


# ------------------------------------------------------------------------------------------ LCP solver
def random_delassus(rng, k):
    J = rng.standard_normal((2 * k, 7))
    A = rng.standard_normal((7, 7))
    Minv = A @ A.T + 0.1 * np.eye(7)
    return J @ Minv @ J.T


@pytest.mark.parametrize("k", [1, 2])
def test_lcp_random_problems_satisfy_complementarity(k):
    rng = np.random.default_rng(k)
    states_seen = set()
    for _ in range(400):
        G = random_delassus(rng, k)
        c = rng.standard_normal(2 * k)
        lam, states, exact = solve_contact_lcp(G, c, MU)
        assert exact
        check_lcp_solution(G, c, lam, MU)
        states_seen.update(int(s) for s in states)
    assert states_seen == {SEPARATE, STICK, SLIDE_POS, SLIDE_NEG}


def test_lcp_stick_inside_cone_and_slide_outside():
    G = np.array([[2.0, 0.3], [0.3, 1.5]])
    # approaching the ground with a small tangential velocity: sticks, |lam_t| < mu lam_n
    lam, states, _ = solve_contact_lcp(G, np.array([-1.0, 0.2]), MU)
    assert states.tolist() == [STICK]
    assert abs(lam[1]) < MU * lam[0]
    assert G[1] @ lam + 0.2 == pytest.approx(0.0, abs=1e-12)
    # a large tangential velocity: slides toward +x with friction on the cone edge, opposing the slip
    lam, states, _ = solve_contact_lcp(G, np.array([-1.0, 5.0]), MU)
    assert states.tolist() == [SLIDE_POS]
    assert lam[1] == pytest.approx(-MU * lam[0], rel=1e-12)
    assert G[1] @ lam + 5.0 > 0.0
    lam, states, _ = solve_contact_lcp(G, np.array([-1.0, -5.0]), MU)
    assert states.tolist() == [SLIDE_NEG]
    assert lam[1] == pytest.approx(MU * lam[0], rel=1e-12)


def test_lcp_lifts_off_exactly_when_the_normal_impulse_would_be_negative():
    G = np.array([[2.0, 0.3], [0.3, 1.5]])
    for cn in np.linspace(-1.0, 1.0, 41):
        lam, states, _ = solve_contact_lcp(G, np.array([cn, 0.0]), MU)
        stick_lam = np.linalg.solve(G, -np.array([cn, 0.0]))  # keeping the foot on the ground needs this
        if stick_lam[0] < 0.0:
            assert states.tolist() == [SEPARATE] and np.all(lam == 0.0)
        else:
            assert states.tolist() == [STICK]
            np.testing.assert_allclose(lam, stick_lam, atol=1e-12)


def test_lcp_frictionless_and_guess_do_not_change_the_solution():
    rng = np.random.default_rng(7)
    G = random_delassus(rng, 2)
    c = np.array([-1.0, 0.5, -0.2, -0.3])
    lam0, states0, _ = solve_contact_lcp(G, c, MU)
    for guess in [(SEPARATE, SEPARATE), (SLIDE_POS, SLIDE_NEG), tuple(states0)]:
        lam, states, _ = solve_contact_lcp(G, c, MU, guess=guess)
        check_lcp_solution(G, c, lam, MU)
    lam, _, _ = solve_contact_lcp(G, c, 0.0)
    assert lam[1] == 0.0 and lam[3] == 0.0
    check_lcp_solution(G, c, lam, 0.0)


def test_lcp_bad_inputs():
    G = np.eye(2)
    with pytest.raises(ValueError, match="c must have shape"):
        solve_contact_lcp(np.eye(3), np.zeros(3), MU)
    with pytest.raises(ValueError, match="G must have shape"):
        solve_contact_lcp(np.eye(4), np.zeros(2), MU)
    with pytest.raises(ValueError, match="finite"):
        solve_contact_lcp(G, np.array([np.nan, 0.0]), MU)
    with pytest.raises(ValueError, match="mu"):
        solve_contact_lcp(G, np.zeros(2), -0.1)
    with pytest.raises(ValueError, match="guess"):
        solve_contact_lcp(G, np.zeros(2), MU, guess=(7,))


# ------------------------------------------------------------------------------------------ simulator
def test_drop_lands_settles_and_stays(robot):
    """Dropped from 5 cm with a PD holding the posture: lands, settles, no penetration > 1 mm, no drift."""
    sim = ContactSimulator(robot)
    x0 = standing_state(robot, lift=0.05)
    sim.set_state(x0)
    lowest, feet_x, trunk = [], [], []
    for _ in range(2000):
        sim.run(pd_hold(sim, x0[:7]), 1)
        pos = sim.foot_positions()
        lowest.append(pos[:, 1].min())
        feet_x.append(pos[:, 0].copy())
        trunk.append(sim.x[:3].copy())
        assert sim.impulse[1] >= 0.0 and sim.impulse[3] >= 0.0
    lowest, feet_x, trunk = np.array(lowest), np.array(feet_x), np.array(trunk)
    assert lowest[:30].min() > 0.0  # still falling at first
    assert lowest.min() > -1e-3  # never more than 1 mm into the ground
    assert sim.contact.all() and sim.lcp_fallbacks == 0
    late = slice(1000, None)  # the last second
    assert np.ptp(feet_x[late], axis=0).max() < 1e-5  # feet do not slide
    assert np.ptp(trunk[late, 0]) < 1e-4  # no horizontal drift
    assert np.ptp(trunk[late, 1]) < 1e-4  # height stays
    assert abs(lowest[-1]) < 1e-5  # resting on the ground
    assert np.abs(sim.v).max() < 1e-3  # at rest


def test_standing_feet_stick_inside_the_cone(robot):
    sim = ContactSimulator(robot)
    x0 = standing_state(robot)
    sim.set_state(x0)
    for _ in range(200):  # the posture sags onto the PD springs
        sim.run(pd_hold(sim, x0[:7]), 1)
    feet = sim.foot_positions()
    for _ in range(500):
        sim.run(pd_hold(sim, x0[:7]), 1)
        for foot in (FRONT, BACK):
            fx, fz = sim.impulse[2 * foot], sim.impulse[2 * foot + 1]
            assert fz > 0.0 and abs(fx) < MU * fz
            assert sim.states[foot] == STICK
    np.testing.assert_allclose(sim.foot_positions(), feet, atol=1e-6)
    assert np.abs(sim.foot_velocities()).max() < 1e-6


def test_feet_pushed_outside_the_cone_slide_with_coulomb_friction(robot):
    """Whole robot given 0.5 m/s forward while standing: the feet slide with |f_x| = mu f_z opposing the slip,
    then stick again."""
    sim = ContactSimulator(robot)
    x0 = standing_state(robot)
    x0[7] = 0.5
    sim.set_state(x0)
    slid = 0
    for _ in range(600):
        sim.run(pd_hold(sim, x0[:7], foot_damping=0.0), 1)
        for foot in (FRONT, BACK):
            fx, fz = sim.impulse[2 * foot], sim.impulse[2 * foot + 1]
            assert fz >= 0.0
            if sim.states[foot] in (SLIDE_POS, SLIDE_NEG):
                slid += 1
                assert fz > 0.0
                sign = 1.0 if sim.states[foot] == SLIDE_NEG else -1.0
                assert fx == pytest.approx(sign * MU * fz, rel=1e-9)  # |lambda_x| = mu lambda_z, against the slip
            elif sim.states[foot] == STICK:
                assert abs(fx) <= MU * fz * (1 + 1e-9)
    assert slid > 30
    assert sim.states == [STICK, STICK]
    assert np.abs(sim.foot_velocities()).max() < 1e-3
    assert sim.foot_positions()[BACK, 0] > robot.foot_positions(x0[:7])[BACK, 0] + 0.005  # it slid forward


def test_ground_never_pulls_under_random_torques(robot):
    sim = ContactSimulator(robot, motor_speed_limits=(36.0, 50.0))
    rng = np.random.default_rng(3)
    x0 = standing_state(robot, lift=0.02)
    sim.set_state(x0)
    fz, contacts = [], 0
    for _ in range(300):
        u = pd_hold(sim, x0[:7]) + rng.uniform(-25.0, 25.0, 4)
        sim.run(np.clip(u, -33, 33), 5)
        fz.extend([sim.impulse[1], sim.impulse[3]])
        contacts += int(sim.contact.any())
    assert contacts > 50
    assert min(fz) >= 0.0
    assert sim.lcp_fallbacks == 0


def test_energy_never_increases_without_gravity_and_torque(robot):
    """Zero gravity, zero torque, thrown at the ground spinning: impacts and friction only remove energy."""
    sim = ContactSimulator(robot, gravity=0.0)
    x0 = standing_state(robot, lift=0.02, pitch=0.1)
    x0[7:] = [0.8, -1.0, 1.5, 2.0, -3.0, 1.0, 2.0]
    sim.set_state(x0)
    energy = [sim.energy()]
    impact = []
    for _ in range(1000):
        before = sim.contact.copy()
        sim.step(np.zeros(4))
        energy.append(sim.energy())
        impact.append(bool(np.any(sim.contact & ~before)))
    energy = np.array(energy)
    d_e = np.diff(energy)
    impact = np.array(impact)
    e0 = energy[0]
    assert impact.sum() >= 2
    assert np.all(d_e <= 1e-5 * e0)  # integration round-off only
    assert energy.max() <= e0 * (1 + 1e-5)
    assert np.all(d_e[impact] < 0.0)  # every touchdown removes energy
    assert energy[-1] < 0.9 * e0


def test_lift_off_exactly_when_the_normal_force_would_become_negative(robot):
    """Standing, then the back knee folds with a growing torque: the back foot leaves the ground at the
    step where the planner's KKT double-stance normal force of that foot turns negative.

    The friction coefficient is set high so that the cone does not bind first (with a finite tangential
    force, ``|f_x| <= mu f_z`` always fails just before ``f_z`` reaches 0 and the foot slips off instead)."""
    sim = ContactSimulator(robot, friction=100.0)
    dyn = HybridDynamics(robot)
    x0 = standing_state(robot)
    sim.set_state(x0)
    for _ in range(300):  # settle
        sim.run(pd_hold(sim, x0[:7]), 1)
    hold_back_knee = pd_hold(sim, x0[:7])[3]
    kkt_sign_change = sim_lift = front_at_lift = None
    for k in range(300):
        u = pd_hold(sim, x0[:7])
        u[3] = hold_back_knee - 0.1 * k  # the back knee torque ramps down: the shank folds toward the thigh
        _, grf = dyn.accelerations(sim.x, u, Mode.DOUBLE_STANCE)
        if kkt_sign_change is None and grf[3] < 0.0:
            kkt_sign_change = k
        sim.run(u, 1)
        if sim_lift is None and sim.states[BACK] == SEPARATE:
            sim_lift = k
            front_at_lift = sim.states[FRONT]
        if sim_lift is None:  # while on the ground the simulator's force is the KKT force
            assert sim.impulse[3] / sim.dt == pytest.approx(grf[3], abs=0.05)
            assert grf[3] > 0.0
    assert kkt_sign_change is not None and sim_lift is not None
    assert sim_lift in (kkt_sign_change - 1, kkt_sign_change)
    assert front_at_lift == STICK  # the front foot stays put while the back foot leaves


@pytest.mark.parametrize("mode", [Mode.DOUBLE_STANCE, Mode.BACK_STANCE])
def test_sticking_stance_agrees_with_the_planner_kkt_model_to_first_order(robot, mode):
    """Same torques, 40 ms of sticking stance: the simulator and HybridDynamics.step (semi-implicit Euler)
    differ by O(h) -- halving h halves the difference."""
    x0 = standing_state(robot)
    if mode == Mode.BACK_STANCE:  # lift the front foot 3 cm by flexing its knee, keep the back foot down
        x0[4] -= 0.35
        x0[1] -= robot.foot_heights(x0[:7])[BACK]
    q = x0[:7]
    J = np.vstack([robot.foot_jacobian(q, f) for f in mode.feet])
    g = pin.computeGeneralizedGravity(robot.model, robot.new_data(), q)
    S = np.zeros((7, 4))
    S[3:] = np.eye(4)
    u = np.linalg.lstsq(np.hstack([S, J.T]), g, rcond=None)[0][:4] + np.array([1.0, -0.5, 0.5, -1.0])
    errors = []
    for h in (1e-3, 5e-4, 2.5e-4):
        dyn = HybridDynamics(robot, dt=h, integrator="semi_implicit")
        sim = ContactSimulator(robot, timestep=h)
        sim.set_state(x0)
        x = x0.copy()
        for _ in range(int(round(0.04 / h))):
            x, grf = dyn.step(x, u, mode)
            sim.step(u)
            for foot in mode.feet:  # the planner's forces stay inside the cone: a sticking stance
                assert grf[2 * foot + 1] > 0.0 and abs(grf[2 * foot]) < MU * grf[2 * foot + 1]
                assert sim.states[foot] == STICK
            assert (sim.contact == [mode.in_contact(FRONT), mode.in_contact(BACK)]).all()
        motion = np.abs(x - x0).max()
        assert motion > 0.05  # the robot really moved
        errors.append(np.abs(sim.x - x).max())
    assert errors[0] < 0.02 * np.abs(x - x0).max()
    assert 1.6 < errors[0] / errors[1] < 2.5 and 1.6 < errors[1] / errors[2] < 2.5


def test_motor_speed_limits(robot):
    sim = ContactSimulator(robot, motor_speed_limits=(36.0, 50.0))
    x = standing_state(robot, lift=0.3)
    x[7 + 3:] = [10.0, 40.0, -45.0, 60.0]
    sim.set_state(x)
    u = np.array([33.0, 33.0, -33.0, 33.0])
    np.testing.assert_allclose(sim.applied_torque(u), [33.0, 33.0 * 10 / 14, -33.0 * 5 / 14, 0.0])
    np.testing.assert_allclose(sim.applied_torque(-u), -u)  # braking is not limited
    # full torque on every joint of a robot floating without gravity: ideal torque sources pump energy
    # without bound (the explicit integration then blows up); the motor limits keep it bounded
    peak = {}
    for limits in (None, (36.0, 50.0)):
        free = ContactSimulator(robot, gravity=0.0, motor_speed_limits=limits)
        free.set_state(standing_state(robot, lift=0.5))
        peak[limits] = 0.0
        for _ in range(100):
            free.run(np.array([33.0, 33.0, -33.0, -33.0]), 10)
            peak[limits] = max(peak[limits], float(np.abs(free.v).max()))
    assert peak[None] > 1e3
    assert peak[(36.0, 50.0)] < 1000.0  # inside the observation bounds (the env's validity check)
    with pytest.raises(ValueError, match="w_full < w_zero"):
        ContactSimulator(robot, motor_speed_limits=(50.0, 36.0))
    with pytest.raises(TypeError, match="motor_speed_limits"):
        ContactSimulator(robot, motor_speed_limits=36.0)


def test_simulator_bad_arguments(robot):
    with pytest.raises(ValueError, match="timestep"):
        ContactSimulator(robot, timestep=0.0)
    with pytest.raises(ValueError, match="friction"):
        ContactSimulator(robot, friction=-1.0)
    with pytest.raises(ValueError, match="erp"):
        ContactSimulator(robot, erp=2.0)
    with pytest.raises(TypeError, match="robot"):
        ContactSimulator("cheetah")
    sim = ContactSimulator(robot)
    with pytest.raises(ValueError, match="x must have shape"):
        sim.set_state(np.zeros(13))
    with pytest.raises(ValueError, match="u must be finite"):
        sim.step(np.array([0.0, np.nan, 0.0, 0.0]))

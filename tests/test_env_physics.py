"""Energy balance, position-level contacts and penetration of the energy-consistent stepping (envs/contact.py),
each also run with the legacy scheme (``energy_consistent=False``) to show what the test catches. The
energy-consistent claims are checked on both implementations of the scheme: the reference
:class:`ContactSimulator` (Python, Pinocchio) and the compiled kernel the env steps through
(:class:`~hsddp_gym.core.compiled_contact.CompiledContactSimulator`)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_env_contact import pd_hold  # noqa: E402  (the tests folder is on sys.path)

from hsddp_gym.core.compiled_contact import CompiledContactSimulator
from hsddp_gym.core.conventions import BACK, FRONT
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.envs.bounding import DEFAULT_MOTOR_SPEED_LIMITS, RESET_VELOCITY_BOUNDS, BoundingEnv
from hsddp_gym.envs.contact import STICK, ContactSimulator

TOL_J = 1e-9  # the energy goal per step [J]
COMBOS = [(False, False), (True, False), (False, True), (True, True)]  # (front, back) starting on the ground
IMPLEMENTATIONS = ("reference", "compiled")


def consistent_sim(kind, robot, **kwargs):
    """The energy-consistent scheme: ``"reference"`` ContactSimulator or ``"compiled"`` (the env's kernel)."""
    return ContactSimulator(robot, **kwargs) if kind == "reference" else CompiledContactSimulator(robot, **kwargs)


@pytest.fixture(scope="module")
def robot():
    return CheetahModel()


def _bisect(f, a, b, n=60):
    fa = f(a)
    for _ in range(n):
        c = 0.5 * (a + b)
        fc = f(c)
        if fa * fc <= 0.0:
            b = c
        else:
            a, fa = c, fc
    return 0.5 * (a + b)


def random_state(robot, rng, combo, vscale):
    """A random state (14,) whose feet ``combo = (front, back)`` touch the ground (the others at least 1 cm
    above it, or 2-100 mm for a flight start), velocities ``vscale * N(0, 1) * [1, 1, 3, 10, 10, 10, 10]``
    clipped to the reset bounds of the env."""
    bounds = np.array(RESET_VELOCITY_BOUNDS)
    while True:
        q = np.zeros(7)
        q[2] = rng.uniform(-0.5, 0.5)
        q[3], q[5] = rng.uniform(-0.5, 1.5, 2)
        q[4], q[6] = rng.uniform(-2.5, -0.5, 2)
        if combo == (True, True):
            def gap(p, q=q):
                return float(np.subtract(*robot.foot_heights(np.r_[q[:2], p, q[3:]])))
            if gap(-0.7) * gap(0.7) > 0.0:
                continue
            q[2] = _bisect(gap, -0.7, 0.7)
            q[1] = -robot.foot_heights(q).min()
        elif combo == (False, False):
            q[1] = -robot.foot_heights(q).min() + rng.uniform(0.002, 0.1)
        else:
            i = FRONT if combo[0] else BACK
            q[1] = -robot.foot_heights(q)[i]
            if robot.foot_heights(q)[1 - i] < 0.01:
                continue
        v = np.clip(rng.standard_normal(7) * vscale * np.array([1, 1, 3, 10, 10, 10, 10]), -bounds, bounds)
        return np.r_[q, v]


def energy_excess(sim, x, steps, u=None):
    """Largest ``E(t+h) - E(t) - tau . dq`` over ``steps`` single steps from ``x`` (applied torques)."""
    sim.set_state(x)
    u = np.zeros(4) if u is None else u
    e = sim.energy()
    worst = -np.inf
    for _ in range(steps):
        q0 = sim.q.copy()
        sim.run(u, 1)
        e1 = sim.energy()
        work = float(sim._tau[3:] @ (sim.q[3:] - q0[3:]))
        worst = max(worst, e1 - e - work)
        e = e1
    return worst


@pytest.mark.parametrize("kind", IMPLEMENTATIONS)
@pytest.mark.parametrize("gravity", [9.81, 0.0, 30.0])
@pytest.mark.parametrize("combo", COMBOS)
def test_energy_never_increases_per_step_with_zero_torque(robot, gravity, combo, kind):
    sim = consistent_sim(kind, robot, gravity=gravity, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS)
    rng = np.random.default_rng(int(gravity * 10) + 7 * combo[0] + 3 * combo[1])
    worst = max(energy_excess(sim, random_state(robot, rng, combo, vscale), 120)
                for vscale in (0.1, 0.3, 1.0, 1.0, 3.0, 10.0))
    assert worst <= TOL_J
    assert sim.lcp_fallbacks == 0 and sim.energy_deficits == 0


@pytest.mark.parametrize("kind", IMPLEMENTATIONS)
@pytest.mark.parametrize("combo", COMBOS)
def test_energy_balance_with_torques(robot, combo, kind):
    """With constant random torques: dE <= tau . dq + 1e-9 J every step (tau: the motors' applied torque)."""
    sim = consistent_sim(kind, robot, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS)
    rng = np.random.default_rng(11 + combo[0] + 2 * combo[1])
    worst = max(energy_excess(sim, random_state(robot, rng, combo, 1.0), 120, rng.uniform(-33.0, 33.0, 4))
                for _ in range(6))
    assert worst <= TOL_J


def test_legacy_scheme_creates_energy(robot):
    """The check above catches the old semi-implicit scheme: it creates energy from the same kind of states."""
    sim = ContactSimulator(robot, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS, energy_consistent=False)
    rng = np.random.default_rng(3)
    worst = max(energy_excess(sim, random_state(robot, rng, combo, 1.0), 120) for combo in COMBOS)
    assert worst > 1e-4


def momentum(sim):
    """Linear x, z and angular y momentum about the centre of mass (3,)."""
    return pin.computeCentroidalMomentum(sim.model, sim.data, sim.q, sim.v).np[[0, 2, 4]].copy()


@pytest.mark.parametrize("kind", IMPLEMENTATIONS)
@pytest.mark.parametrize("rate", [10.0, 50.0, 100.0, 300.0])
def test_free_flight_conserves_momentum_and_energy(robot, rate, kind):
    """g = 0, no torque, 2 m above the ground, the trunk moving and pitching and the joints spinning at up to
    ``rate`` rad/s: over 10 s (10,000 steps) the linear and the angular momentum about the centre of mass are
    conserved to 1e-9 relative and the energy to 1e-6 relative (the goal: 1e-3); no step raises the energy.
    The legacy semi-implicit scheme (``energy_consistent=False``) gains energy (x13 in 0.5 s at 100 rad/s) and the
    step the default scheme had before lost 49 % of it in 0.5 s at 100 rad/s and drifted in momentum."""
    x = np.zeros(14)
    x[1] = 2.0
    x[3:7] = 0.7, -1.4, 0.7, -1.4
    x[7], x[8], x[9] = 1.0, 0.3, 2.0  # up and forward: the CoM rises 3 m in the 10 s
    x[10:14] = rate, -0.5 * rate, 0.3 * rate, -0.8 * rate
    sim = consistent_sim(kind, robot, gravity=0.0)
    sim.set_state(x)
    e0, p0 = sim.energy(), momentum(sim)
    e, rises = e0, 0.0
    for _ in range(10):
        for _ in range(1000):
            sim.run(np.zeros(4), 1)
            e1 = sim.energy()
            rises = max(rises, e1 - e)
            e = e1
        p = momentum(sim)
        assert np.linalg.norm(p[:2] - p0[:2]) <= 1e-9 * np.linalg.norm(p0[:2])
        assert abs(p[2] - p0[2]) <= 1e-9 * abs(p0[2])
    assert sim.time == pytest.approx(10.0)
    assert rises <= TOL_J
    assert abs(e / e0 - 1.0) <= 1e-6
    assert sim.momentum_fallbacks == 0 and not sim.contact.any()
    legacy = ContactSimulator(robot, gravity=0.0, energy_consistent=False)
    legacy.set_state(x)
    with np.errstate(all="ignore"):
        legacy.run(np.zeros(4), 500)
        assert rate < 50.0 or not np.isfinite(legacy.energy()) or legacy.energy() > 1.001 * e0


def rk4_flight(robot, x, tau, duration, h=1e-4):
    """An independent reference: classical RK4 on ``qdd = ABA(q, v, tau)`` (free flight, no contact) with step
    ``h``; returns ``(q, v)`` at ``duration``."""
    model, data = robot.model, robot.model.createData()
    q, v = x[:7].copy(), x[7:].copy()

    def f(q, v):
        return v, pin.aba(model, data, q, v, tau)

    for _ in range(int(round(duration / h))):
        k1 = f(q, v)
        k2 = f(q + 0.5 * h * k1[0], v + 0.5 * h * k1[1])
        k3 = f(q + 0.5 * h * k2[0], v + 0.5 * h * k2[1])
        k4 = f(q + h * k3[0], v + h * k3[1])
        q = q + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
        v = v + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    return q, v


@pytest.mark.parametrize("kind", IMPLEMENTATIONS)
def test_flight_under_gravity_and_torques_follows_the_impulse_and_the_work(robot, kind):
    """0.3 s of flight with g = 9.81 and constant torques of up to 3 N m (the legs reach hundreds of rad/s): the
    momentum changes by exactly gravity's impulse ``(0, -m g t, 0)``, and the energy gain is within 6 % of the
    exact one (an RK4 reference at 0.1 ms) and at least 5x nearer to it than the semi-implicit scheme's
    (measured: errors of 3.8 %, 5.1 %, 4.4 % against 42 %, 71 %, 30 %; first order: they halve with the step).
    The work per step is taken second order in the step, where ``tau . h v+`` counts the torques' own
    acceleration twice."""
    rng = np.random.default_rng(5)
    for _ in range(3):
        x = np.zeros(14)
        x[1] = 4.0
        x[3:7] = 0.7, -1.4, 0.7, -1.4
        x[7:] = rng.normal(0.0, 1.0, 7) * np.array([1, 1, 2, 20, 20, 20, 20])
        u = rng.uniform(-3.0, 3.0, 4)
        tau = np.r_[np.zeros(3), u]
        gains = {}
        for consistent in (True, False):
            sim = consistent_sim(kind, robot) if consistent else ContactSimulator(robot, energy_consistent=False)
            sim.set_state(x)
            p0, e0 = momentum(sim), sim.energy()
            sim.run(u, 300)
            assert not sim.contact.any() and robot.foot_heights(sim.q).min() > 0.5
            gains[consistent] = sim.energy() - e0
            if consistent:
                expected = p0 + np.array([0.0, -robot.total_mass * 9.81 * sim.time, 0.0])
                np.testing.assert_allclose(momentum(sim), expected, rtol=0, atol=1e-9 * np.abs(expected).max())
        q_ref, v_ref = rk4_flight(robot, x, tau, 0.3)
        exact = float(tau @ (q_ref - x[:7]))  # the torques' work = the energy gain of the exact flight
        assert abs(gains[True] - exact) <= 0.06 * abs(exact)
        assert abs(gains[True] - exact) <= 0.2 * abs(gains[False] - exact)


def stick_drift(robot, consistent: bool, kind: str = "reference") -> tuple[float, int]:
    """``(largest one-step movement [m] of a sticking foot, foot-steps spent sticking)`` over a 200 ms stance on
    both feet with the trunk rocking (PD on the joints, an initial pitch rate)."""
    sim = consistent_sim(kind, robot) if consistent else ContactSimulator(robot, energy_consistent=False)
    q = np.array([0.0, 0.0, 0.0, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])
    q[1] = -robot.foot_heights(q).min()
    x = np.r_[q, np.zeros(7)]
    x[7], x[9] = 0.3, 1.5
    sim.set_state(x)
    worst, stick_steps = 0.0, 0
    feet = sim.foot_positions()
    for _ in range(200):
        sim.run(pd_hold(sim, x[:7]), 1)
        new = sim.foot_positions()
        for foot in (FRONT, BACK):
            if sim.states[foot] == STICK:
                worst = max(worst, float(np.abs(new[foot] - feet[foot]).max()))
                stick_steps += 1
        feet = new
    return worst, stick_steps


@pytest.mark.parametrize("consistent, kind", [(True, "reference"), (True, "compiled"), (False, "reference")])
def test_sticking_feet_do_not_creep(robot, consistent, kind):
    """While a foot sticks it moves by at most 1e-9 m per step (the legacy velocity-level stick creeps ~1e-6 m)."""
    worst, stick_steps = stick_drift(robot, consistent, kind)
    assert stick_steps >= 300
    if consistent:
        assert worst <= 1e-9
    else:
        assert worst > 1e-7


@pytest.mark.parametrize("kind", IMPLEMENTATIONS)
@pytest.mark.parametrize("speed", [1.0, 5.0, 10.0])
@pytest.mark.parametrize("pitch", [0.0, 0.2])
def test_landing_penetrates_at_most_one_millimetre(robot, speed, pitch, kind):
    """Dropped onto the ground at ``speed`` m/s (zero torque, so the legs fold): no foot is ever more than
    1 mm below the ground at the end of a step."""
    sim = consistent_sim(kind, robot, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS)
    q = np.array([0.0, 0.0, pitch, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])
    q[1] = -robot.foot_heights(q).min() + 0.02
    x = np.r_[q, np.zeros(7)]
    x[7], x[8] = 0.5, -speed
    sim.set_state(x)
    lowest = np.inf
    for _ in range(300):
        sim.run(np.zeros(4), 1)
        lowest = min(lowest, float(sim.foot_heights().min()))
    assert lowest >= -1e-3
    assert np.all(np.isfinite(sim.x)) and sim.lcp_fallbacks == 0
    if speed == 10.0 and kind == "reference":  # the legacy scheme sinks deeper than that
        legacy = ContactSimulator(robot, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS, energy_consistent=False)
        legacy.set_state(x)
        deepest = np.inf
        for _ in range(300):
            legacy.run(np.zeros(4), 1)
            deepest = min(deepest, float(legacy.foot_heights().min()))
        assert deepest < -1e-3


def test_env_energy_with_zero_action_from_accepted_reset_states():
    """Through the env (200 Hz, frame_skip 5): from states at the reset bounds, zero action, g = 0, the energy
    never increases per control step and nothing blows up (the env steps through the compiled kernel)."""
    env = BoundingEnv(gravity=0.0, terminate_when_unhealthy=False)
    assert isinstance(env.sim, CompiledContactSimulator)
    rng = np.random.default_rng(5)
    bounds = np.array(RESET_VELOCITY_BOUNDS)
    for _ in range(6):
        x = random_state(env.robot, rng, COMBOS[rng.integers(4)], 1.0)
        x[7:] = bounds * rng.choice([-1.0, 1.0], 7) * rng.uniform(0.5, 1.0, 7)
        env.reset(options={"state": x})
        e = env.sim.energy()
        for _ in range(100):
            _, _, terminated, _, info = env.step(np.zeros(4))
            assert not info["invalid_state"]
            e1 = env.sim.energy()
            assert e1 - e <= TOL_J
            e = e1


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_spd_solver_of_the_position_projection(n):
    from hsddp_gym.core.contact_lcp import solve_spd

    rng = np.random.default_rng(n)
    for _ in range(200):
        J = rng.standard_normal((n, 7))
        S = J @ J.T + 1e-3 * np.eye(n)
        r = rng.standard_normal(n)
        z = np.array(solve_spd(S.tolist(), r.tolist()))
        np.testing.assert_allclose(S @ z, r, atol=1e-9)
    if n > 1:
        singular = np.ones((n, n))
        assert solve_spd(singular.tolist(), [1.0] * n) is None


def test_no_blow_up_from_accepted_reset_states():
    """50 reset states with every speed drawn up to its reset bound (10 m/s, 50 and 100 rad/s), 100 control
    steps each of zero and of random actions (g = 9.81): no invalid state. The same loop with
    ``energy_consistent=False`` ended 3 of its 50 zero-action runs in an invalid state."""
    env = BoundingEnv(terminate_when_unhealthy=False)
    rng = np.random.default_rng(0)
    bounds = np.array(RESET_VELOCITY_BOUNDS)
    for k in range(50):
        x = random_state(env.robot, rng, COMBOS[k % 4], 1.0)
        x[7:] = bounds * rng.uniform(-1.0, 1.0, 7)
        for mode in ("zero", "random"):
            env.reset(options={"state": x})
            for _ in range(100):
                action = np.zeros(4) if mode == "zero" else rng.uniform(-1.0, 1.0, 4)
                _, _, _, _, info = env.step(action)
                assert not info["invalid_state"]


def bound_state(robot, rng) -> np.ndarray:
    """A start state the env accepts, its velocities drawn up to 98 % of ``RESET_VELOCITY_BOUNDS`` (joints up to
    98 rad/s) and its lowest foot 1 mm above the ground (14,)."""
    q = np.array([0.0, 0.0, rng.uniform(-0.3, 0.3), rng.uniform(-1, 1), rng.uniform(-2, -0.5),
                  rng.uniform(-1, 1), rng.uniform(-2, -0.5)])
    q[1] = 0.001 - robot.foot_heights(q).min()
    return np.r_[q, rng.uniform(-0.98, 0.98, 7) * np.array(RESET_VELOCITY_BOUNDS)]


@pytest.mark.parametrize("motor_limits", [True, False], ids=["motor_limits", "ideal_torques"])
@pytest.mark.parametrize("actions", ["zero", "bang_bang"])
def test_no_tunnelling_from_bound_states(motor_limits, actions):
    """Through the env: 40 start states at the reset bounds, 1 s each of zero action or of actions alternating
    between -1 and +1 every control step: no foot ever ends a control step more than 1 mm below the ground (the
    scheme the env had before sank 37.9 mm from such states with zero action, 1.25 mm bang-bang, 4-7 mm with
    ideal torques)."""
    env = BoundingEnv(terminate_when_unhealthy=False,
                      **({} if motor_limits else {"motor_speed_limits": None}))
    rng = np.random.default_rng(43 + 2 * motor_limits + (actions == "zero"))
    deepest = 0.0
    for k in range(40):
        env.reset(seed=k, options={"state": bound_state(env.robot, rng)})
        for t in range(200):
            a = np.zeros(4) if actions == "zero" else np.full(4, 1.0 if t % 2 == 0 else -1.0)
            _, _, _, _, info = env.step(a)
            if info["invalid_state"]:  # refused from here on; never seen with these states
                break
            deepest = max(deepest, -float(np.min(info["foot_heights"])))
    assert deepest <= 1e-3


@pytest.mark.parametrize("kind", IMPLEMENTATIONS)
def test_no_tunnelling_in_any_physics_step(robot, kind):
    """Every 1 ms step (not just every control step): 10 bound states, 0.3 s of bang-bang joint torques (the
    torque limit, sign flipped every 5 ms) without motor speed limits: the lowest foot never ends a step more
    than 1 mm below the ground, and the energy balance holds in every step."""
    rng = np.random.default_rng(7)
    limit = BoundingEnv().torque_limit
    deepest, worst_excess = 0.0, -np.inf
    for _ in range(10):
        sim = consistent_sim(kind, robot)
        sim.set_state(bound_state(robot, rng))
        e = sim.energy()
        for t in range(300):
            q0 = sim.q.copy()
            sim.run(np.full(4, limit if (t // 5) % 2 == 0 else -limit), 1)
            e1 = sim.energy()
            worst_excess = max(worst_excess, e1 - e - float(sim._tau[3:] @ (sim.q[3:] - q0[3:])))
            e = e1
            deepest = max(deepest, -float(sim.foot_heights().min()))
        assert np.all(np.isfinite(sim.x))
    assert deepest <= 1e-3
    assert worst_excess <= TOL_J

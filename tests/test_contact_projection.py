"""The position projection's shortcuts (hsddp_gym/core/contact.py): the exact Newton-remainder bound that lets it
skip the last placement check, and the straight-line first Newton step for two sticking feet."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hsddp_gym.core.contact import POSITION_TOLERANCE, ContactSimulator
from hsddp_gym.core.contact_lcp import STICK


def test_newton_remainder_bound_bounds_the_foot_kinematics_remainder():
    """``|p(q + dq) - p(q) - J dq| <= bound`` per coordinate at random configurations and step sizes, and the
    bound is tight (the worst ratio is close to 1), so skipping the check never changes an iteration count."""
    sim = ContactSimulator()
    model, data = sim.model, sim.data
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(500):
        q = rng.normal(size=7)
        dq = rng.normal(size=7) * 10.0 ** rng.uniform(-6, -1)
        for foot, fid in enumerate(sim._fids):
            J = pin.computeFrameJacobian(model, data, q, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            p0 = pin.updateFramePlacement(model, data, fid).translation.copy()
            pin.forwardKinematics(model, data, q + dq)
            p1 = pin.updateFramePlacement(model, data, fid).translation
            remainder = np.abs(p1 - p0 - J[:3] @ dq)[[0, 2]].max()
            worst = max(worst, remainder / sim._newton_remainder_bound(dq.tolist(), (foot,)))
    assert 0.9 < worst <= 1.0 + 1e-6, worst


def test_double_stick_shortcut_equals_the_general_projection(monkeypatch):
    """A standing robot under a joint PD (both feet sticking most steps): the straight-line first Newton step gives the
    general iteration's result to round-off, step by step."""
    q = np.array([0.0, 0.0, 0.0, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])
    fast, general = ContactSimulator(), ContactSimulator()
    q[1] = -fast.robot.foot_heights(q).min()
    x0 = np.concatenate([q, np.zeros(7)])
    monkeypatch.setattr(general, "_project_double_stick", lambda cand, q_old: False)
    fast.set_state(x0)
    general.set_state(x0)
    sticking = 0
    for k in range(300):
        u = 60.0 * (q[3:] + 0.1 * np.sin(0.02 * k) - fast.q[3:]) - 1.0 * fast.v[3:]
        fast.step(u)
        general.step(u)
        sticking += fast.states == [STICK, STICK]
        assert fast.states == general.states
        np.testing.assert_allclose(fast.x, general.x, rtol=0, atol=1e-12)
    assert sticking > 100
    assert fast.projection_residual <= POSITION_TOLERANCE and general.projection_residual <= POSITION_TOLERANCE

"""The compiled planar dynamics (``hsddp_gym.core.planar_dynamics``): Pinocchio's numbers to rounding, derivatives
against finite differences, the contact constraint held, the generated file up to date, and the guard against
models of another structure."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hsddp_gym.core.conventions import NQ, NV, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics, Linearization
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.params import LinkParams, RobotParams
from hsddp_gym.core.planar_dynamics import Scratch, kernel_params, knot_dynamics, linearize_knots, rollout_phase

DYN = HybridDynamics()
P = kernel_params(DYN.robot)
MODES = (0, 1, 2, 3)


def _states(n: int, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q = rng.uniform(-1.0, 1.0, NQ)
        q[1] += 0.3
        v = rng.uniform(-4.0, 4.0, NV)
        tau = np.zeros(NV)
        tau[3:] = rng.uniform(-33.0, 33.0, 4)
        yield q, v, tau


def _compiled(q, v, tau, mode, p=P):
    out = {"a": np.zeros(NV), "lam": np.zeros(6), "a_q": np.zeros((NV, NV)), "a_v": np.zeros((NV, NV)),
           "a_tau": np.zeros((NV, NV)), "l_q": np.zeros((6, NV)), "l_v": np.zeros((6, NV)), "l_tau": np.zeros((6, NV))}
    assert knot_dynamics(q, v, tau, mode, p, True, Scratch().arrays, out["a"], out["lam"], out["a_q"], out["a_v"],
                         out["a_tau"], out["l_q"], out["l_v"], out["l_tau"])
    return out


def _pinocchio(q, v, tau, mode, dyn=DYN):
    if mode == 0:
        dq, dv, minv = pin.computeABADerivatives(dyn.model, dyn._free, q, v, tau)
        return {"a": dyn._free.ddq.copy(), "a_q": dq.copy(), "a_v": dv.copy(), "a_tau": minv.copy()}
    cs = dyn._contact[Mode(mode)]
    a = pin.constraintDynamics(dyn.model, cs.data, q, v, tau, cs.models, cs.datas, dyn._prox).copy()
    lam = cs.data.lambda_c.copy()
    dq, dv, dt, lq, lv, lt = (m.copy() for m in pin.computeConstraintDynamicsDerivatives(dyn.model, cs.data,
                                                                                          cs.models, cs.datas,
                                                                                          dyn._prox))
    return {"a": a, "lam": lam, "a_q": dq, "a_v": dv, "a_tau": dt, "l_q": lq, "l_v": lv, "l_tau": lt}


@pytest.mark.parametrize("mode", MODES)
def test_knot_dynamics_and_derivatives_are_pinocchios(mode):
    for q, v, tau in _states(25, seed=mode):
        got, ref = _compiled(q, v, tau, mode), _pinocchio(q, v, tau, mode)
        for name, value in ref.items():
            rows = value.shape[0] if name in ("lam", "l_q", "l_v", "l_tau") else None  # 3 per foot in contact
            np.testing.assert_allclose(got[name][:rows], value, rtol=1e-10, atol=1e-9, err_msg=f"{name}, mode {mode}")


@pytest.mark.parametrize("mode", MODES)
def test_derivatives_match_central_finite_differences(mode):
    eps = 1e-6
    for q, v, tau in _states(5, seed=10 + mode):
        got = _compiled(q, v, tau, mode)
        nl = 3 * bin(mode).count("1")
        for name, lname, base in (("a_q", "l_q", 0), ("a_v", "l_v", 1), ("a_tau", "l_tau", 2)):
            for j in range(NV):
                plus, minus = [z.copy() for z in (q, v, tau)], [z.copy() for z in (q, v, tau)]
                plus[base][j] += eps
                minus[base][j] -= eps
                hi, lo = _compiled(*plus, mode), _compiled(*minus, mode)
                np.testing.assert_allclose(got[name][:, j], (hi["a"] - lo["a"]) / (2 * eps), rtol=1e-5, atol=1e-4,
                                           err_msg=f"{name}[:, {j}], mode {mode}")
                np.testing.assert_allclose(got[lname][:nl, j], (hi["lam"][:nl] - lo["lam"][:nl]) / (2 * eps),
                                           rtol=1e-5, atol=1e-4, err_msg=f"{lname}[:, {j}], mode {mode}")


@pytest.mark.parametrize("mode", (1, 2, 3))
def test_feet_in_contact_do_not_accelerate_and_the_y_rows_are_zero(mode):
    robot = DYN.robot
    data = robot.model.createData()
    for q, v, tau in _states(10, seed=20 + mode):
        got = _compiled(q, v, tau, mode)
        pin.forwardKinematics(robot.model, data, q, v, got["a"])
        pin.updateFramePlacements(robot.model, data)
        for i, foot in enumerate(f for f in (0, 1) if mode & (1 << f)):
            acc = pin.getFrameClassicalAcceleration(robot.model, data, robot.foot_frame_ids[foot],
                                                    pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).linear
            np.testing.assert_allclose(acc, 0.0, atol=1e-9)
            assert got["lam"][3 * i + 1] == 0.0 and not got["l_q"][3 * i + 1].any()


def test_rollout_phase_steps_like_hybrid_dynamics_step():
    dyn = HybridDynamics(dt=0.0025, integrator="semi_implicit")
    n, mode = 6, 3
    rng = np.random.default_rng(3)
    X = np.zeros((n + 1, NX))
    X[0, 1], X[0, NQ] = 0.3, 1.0
    U, K, c = np.zeros((n, 4)), rng.normal(0.0, 5.0, (n, 4, NX)), rng.normal(0.0, 5.0, (n, 4))
    lam6, acc, tau = np.zeros((n, 6)), np.zeros((n, NV)), np.zeros(NV)
    lin = Linearization(n)
    failed = rollout_phase(X, U, K, c, True, 0, n, mode, 0.0025, True, P, True, Scratch().arrays, tau, lam6, acc,
                           lin.a_q, lin.a_v, lin.a_tau, lin.lam6_q, lin.lam6_v, lin.lam6_tau)
    assert failed == -1
    x = X[0].copy()
    for k in range(n):
        u = K[k] @ x + c[k]
        np.testing.assert_allclose(U[k], u, rtol=1e-12, atol=1e-12)
        x, grf = dyn.step(x, u, Mode(mode))
        np.testing.assert_allclose(X[k + 1], x, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(lam6[k, [0, 2, 3, 5]], grf, rtol=1e-9, atol=1e-9)


def test_linearize_writes_pinocchios_derivatives():
    rng = np.random.default_rng(4)
    n = 8
    X = np.array([np.concatenate([q, v]) for q, v, _ in _states(n + 1, seed=5)])
    U = rng.uniform(-30.0, 30.0, (n, 4))
    modes = np.array([0, 1, 2, 3, 3, 2, 1, 0])
    lin = Linearization(n)
    DYN.linearize(X, U, modes, lin)
    for k in range(n):
        tau = np.zeros(NV)
        tau[3:] = U[k]
        ref = _pinocchio(X[k, :NQ], X[k, NQ:], tau, modes[k])
        np.testing.assert_allclose(lin.a_q[k], ref["a_q"], rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(lin.a_tau[k], ref["a_tau"], rtol=1e-10, atol=1e-9)
        if modes[k]:
            nl = ref["lam"].size
            np.testing.assert_allclose(lin.lam6[k, :nl], ref["lam"], rtol=1e-10, atol=1e-9)
            np.testing.assert_allclose(lin.lam6_v[k, :nl], ref["l_v"], rtol=1e-10, atol=1e-9)


def test_a_non_finite_state_fails_the_knot():
    q, v, tau = next(_states(1, seed=6))
    q[2] = np.nan
    out = [np.zeros(NV), np.zeros(6), *(np.zeros((NV, NV)) for _ in range(3)), *(np.zeros((6, NV)) for _ in range(3))]
    assert not knot_dynamics(q, v, tau, 1, P, True, Scratch().arrays, *out)
    X = np.zeros((3, NX))
    X[1, 2] = np.nan  # the pitch (the x position does not enter the dynamics)
    assert linearize_knots(X, np.zeros((2, 4)), np.zeros(2, dtype=np.int64), P, Scratch().arrays, np.zeros(NV),
                           np.zeros((2, 6)), np.zeros((2, NV)), *(np.zeros((2, NV, NV)) for _ in range(3)),
                           *(np.zeros((2, 6, NV)) for _ in range(3))) == 1


def test_parameters_come_from_the_pinocchio_model():
    params = RobotParams(trunk=LinkParams(mass=6.3, com_z=0.01, inertia_yy=0.2), hip_offset=0.21)
    robot = CheetahModel(params)
    robot.model.gravity = pin.Motion(np.array([0.0, 0.0, -3.7]), np.zeros(3))
    p = kernel_params(robot)
    np.testing.assert_allclose(p[[0, 2, 11, 12]], [6.3, 0.01, 0.21, 3.7], rtol=1e-12)
    dyn = HybridDynamics(robot)
    for q, v, tau in _states(3, seed=7):
        np.testing.assert_allclose(_compiled(q, v, tau, 3, p)["a"], _pinocchio(q, v, tau, 3, dyn)["a"], rtol=1e-10,
                                   atol=1e-9)


def test_a_model_of_another_structure_is_refused():
    robot = CheetahModel()
    robot.model.inertias[4] = pin.Inertia(1.0, np.array([0.01, 0.0, -0.02]), np.eye(3) * 0.01)  # CoM off the link
    with pytest.raises(ValueError, match="robot: its Pinocchio model is not the planar Mini Cheetah"):
        kernel_params(robot)
    with pytest.raises(TypeError, match="robot must be a CheetahModel"):
        kernel_params(RobotParams())


def test_the_generated_terms_are_what_the_generator_writes():
    """Text for text with the sympy that generated the file (another version may print the same terms otherwise;
    the tests above check the numbers whatever printed them)."""
    sympy = pytest.importorskip("sympy")
    from hsddp_gym.core.planar_codegen import SYMPY_TAG, TARGET, generate

    text = TARGET.read_text()
    if f"{SYMPY_TAG}{sympy.__version__}\n" not in text:
        pytest.skip(f"the file was generated with another sympy than {sympy.__version__}")
    assert text == generate(), "run python -m hsddp_gym.core.planar_codegen"

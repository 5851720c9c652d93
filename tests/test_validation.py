"""Bad input: every public entry point raises ValueError/TypeError whose message names the argument."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hsddp_gym.core.conventions import NQ, NU, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics, Linearization
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.params import LinkParams, RobotParams
from hsddp_gym.core.references import end_of_mode_reference, paper_initial_state
from hsddp_gym.core.rollout import rollout
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController
from hsddp_gym.util.validation import check_array, check_in_range, check_int, check_positive, check_vector

X0 = paper_initial_state()
Q0 = X0[:NQ]
U0 = np.zeros(NU)
ROBOT = CheetahModel()
DYN = HybridDynamics(ROBOT)
SCHEDULE = ModeSchedule([Mode.BACK_STANCE, Mode.FLIGHT], [0.004, 0.003])
NH = 4
"""Knots of the small horizon given to ``linearize``."""
XH = np.tile(X0, (NH + 1, 1))
UH = np.zeros((NH, NU))
MH = np.array([int(Mode.BACK_STANCE), int(Mode.FLIGHT), int(Mode.FRONT_STANCE), int(Mode.DOUBLE_STANCE)])


def _with(arr: np.ndarray, index: int, value: float) -> np.ndarray:
    out = np.array(arr, dtype=np.float64)
    out[index] = value
    return out


# ----------------------------------------------------------------------------------------- validation helpers
def test_check_vector():
    out = check_vector([1, 2, 3], 3, "v")
    assert out.dtype == np.float64 and out.tolist() == [1.0, 2.0, 3.0]
    with pytest.raises(ValueError, match=r"v must have shape \(3,\), got \(2,\)"):
        check_vector([1, 2], 3, "v")
    with pytest.raises(ValueError, match="v must have shape"):
        check_vector(np.zeros((3, 1)), 3, "v")
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(ValueError, match="v must be finite"):
            check_vector([0.0, bad, 0.0], 3, "v")
    for bad in ("abc", object(), [1, "a", 2]):
        with pytest.raises(TypeError, match="v must be an array of 3 numbers"):
            check_vector(bad, 3, "v")


def test_check_array():
    assert check_array([[1, 2]], (None, 2), "A").shape == (1, 2)
    with pytest.raises(ValueError, match=r"A must have shape \(None, 2\)"):
        check_array(np.zeros((2, 3)), (None, 2), "A")
    with pytest.raises(ValueError, match="A must have shape"):
        check_array(np.zeros(2), (None, 2), "A")
    with pytest.raises(ValueError, match="A must be finite"):
        check_array([[1.0, np.nan]], (1, 2), "A")
    with pytest.raises(TypeError, match="A must be a numeric array"):
        check_array("x", (1,), "A")


def test_check_positive_int_and_range():
    assert check_positive(np.float32(0.5), "h") == 0.5
    assert check_positive(0, "h", allow_zero=True) == 0.0
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="h must be a finite number > 0"):
            check_positive(bad, "h")
    with pytest.raises(ValueError, match="h must be a finite number >= 0"):
        check_positive(-1e-9, "h", allow_zero=True)
    for bad in (True, "1", None, 1j, [1.0]):
        with pytest.raises(TypeError, match="h must be a real number"):
            check_positive(bad, "h")

    assert check_int(np.int64(3), "n", minimum=1) == 3
    with pytest.raises(ValueError, match="n must be >= 1, got 0"):
        check_int(0, "n", minimum=1)
    for bad in (True, 1.0, "1", None):
        with pytest.raises(TypeError, match="n must be an integer"):
            check_int(bad, "n")

    assert check_in_range(1, 0.0, 1.0, "e") == 1.0
    for bad in (-0.01, 1.01, math.nan, math.inf):
        with pytest.raises(ValueError, match=r"e must be in \[0.0, 1.0\]"):
            check_in_range(bad, 0.0, 1.0, "e")
    for bad in (False, "0.5", None):
        with pytest.raises(TypeError, match="e must be a real number"):
            check_in_range(bad, 0.0, 1.0, "e")


# ----------------------------------------------------------------------------------------- the API
# (id, call, exception, argument name the message must contain)
CASES = [
    # HybridDynamics construction
    ("dyn-dt-zero", lambda: HybridDynamics(dt=0.0), ValueError, "dt"),
    ("dyn-dt-negative", lambda: HybridDynamics(dt=-1e-3), ValueError, "dt"),
    ("dyn-dt-nan", lambda: HybridDynamics(dt=math.nan), ValueError, "dt"),
    ("dyn-dt-inf", lambda: HybridDynamics(dt=math.inf), ValueError, "dt"),
    ("dyn-dt-str", lambda: HybridDynamics(dt="1e-3"), TypeError, "dt"),
    ("dyn-dt-none", lambda: HybridDynamics(dt=None), TypeError, "dt"),
    ("dyn-integrator", lambda: HybridDynamics(integrator="rk4"), ValueError, "integrator"),
    ("dyn-integrator-none", lambda: HybridDynamics(integrator=None), ValueError, "integrator"),
    ("dyn-robot", lambda: HybridDynamics(robot="cheetah"), TypeError, "robot"),
    ("linearization-capacity-zero", lambda: Linearization(0), ValueError, "capacity"),
    ("linearization-capacity-negative", lambda: Linearization(-5), ValueError, "capacity"),
    # CheetahModel
    ("model-params", lambda: CheetahModel(params="mini cheetah"), TypeError, "params"),
    ("model-q-short", lambda: ROBOT.foot_positions(np.zeros(6)), ValueError, "q"),
    ("model-q-nan", lambda: ROBOT.foot_heights(_with(Q0, 2, np.nan)), ValueError, "q"),
    ("model-q-type", lambda: ROBOT.hip_positions("q"), TypeError, "q"),
    ("model-link-points-q", lambda: ROBOT.link_points(np.zeros(NX)), ValueError, "q"),
    ("model-x-short", lambda: ROBOT.foot_velocities(Q0), ValueError, "x"),
    ("model-x-inf", lambda: ROBOT.foot_velocities(_with(X0, 9, np.inf)), ValueError, "x"),
    ("model-foot-2", lambda: ROBOT.foot_jacobian(Q0, 2), ValueError, "foot"),
    ("model-foot-str", lambda: ROBOT.foot_jacobian(Q0, "front"), ValueError, "foot"),
    ("model-height-foot", lambda: ROBOT.foot_height_derivatives(Q0, -1), ValueError, "foot"),
    ("model-height-q", lambda: ROBOT.foot_height_derivatives(np.zeros(5), 0), ValueError, "q"),
    ("model-jacobian-q", lambda: ROBOT.foot_jacobian(np.zeros(8), 0), ValueError, "q"),
    # parameters
    ("link-mass", lambda: LinkParams(mass=0.0, com_z=0.0, inertia_yy=1.0), ValueError, "mass"),
    ("link-mass-nan", lambda: LinkParams(mass=math.nan, com_z=0.0, inertia_yy=1.0), ValueError, "mass"),
    ("link-inertia", lambda: LinkParams(mass=1.0, com_z=0.0, inertia_yy=-1.0), ValueError, "inertia_yy"),
    ("link-length", lambda: LinkParams(mass=1.0, com_z=0.0, inertia_yy=1.0, length=-0.1), ValueError, "length"),
    ("robot-gravity", lambda: RobotParams(gravity=0.0), ValueError, "gravity"),
    ("robot-friction", lambda: RobotParams(friction=-0.6), ValueError, "friction"),
    ("robot-torque-limit", lambda: RobotParams(torque_limit=math.inf), ValueError, "torque_limit"),
    ("robot-hip-offset", lambda: RobotParams(hip_offset=0.0), ValueError, "hip_offset"),
    ("robot-trunk", lambda: RobotParams(trunk=5.46), TypeError, "trunk"),
    # ModeSchedule
    ("schedule-modes-unknown", lambda: ModeSchedule([7], [0.1]), ValueError, "modes"),
    ("schedule-modes-empty", lambda: ModeSchedule([], []), ValueError, "modes"),
    ("schedule-modes-none", lambda: ModeSchedule(None, [0.1]), ValueError, "modes"),
    ("schedule-durations-zero", lambda: ModeSchedule([0], [0.0]), ValueError, "durations"),
    ("schedule-durations-negative", lambda: ModeSchedule([0, 1], [0.1, -0.1]), ValueError, "durations"),
    ("schedule-durations-nan", lambda: ModeSchedule([0], [math.nan]), ValueError, "durations"),
    ("schedule-durations-length", lambda: ModeSchedule([0, 1], [0.1]), ValueError, "durations"),
    ("schedule-final-mode", lambda: ModeSchedule([0], [0.1], final_mode=9), ValueError, "final_mode"),
    ("bounding-cycles-zero", lambda: ModeSchedule.bounding(0), ValueError, "cycles"),
    ("bounding-cycles-float", lambda: ModeSchedule.bounding(1.5), TypeError, "cycles"),
    ("bounding-cycles-str", lambda: ModeSchedule.bounding("5"), TypeError, "cycles"),
    ("bounding-durations", lambda: ModeSchedule.bounding(2, durations=[0.1] * 3), ValueError, "durations"),
    ("bounding-durations-negative", lambda: ModeSchedule.bounding(1, durations=[0.1, -0.1, 0.1, 0.1]), ValueError,
     "durations"),
    ("bounding-start", lambda: ModeSchedule.bounding(1, start=Mode.FLIGHT), ValueError, "start"),
    ("knots-dt-zero", lambda: SCHEDULE.knots(0.0), ValueError, "dt"),
    ("knots-dt-str", lambda: SCHEDULE.knots("1e-3"), TypeError, "dt"),
    ("with-durations", lambda: SCHEDULE.with_durations([0.1, 0.0]), ValueError, "durations"),
    ("schedule-modes-bool", lambda: ModeSchedule([True], [0.1]), TypeError, "modes"),
    ("schedule-final-mode-bool", lambda: ModeSchedule([0], [0.1], final_mode=False), TypeError, "final_mode"),
    # HybridDynamics.linearize (public horizon entry point of the solver)
    ("linearize-U-shape", lambda: DYN.linearize(XH, np.zeros((NH, 3)), MH, Linearization(NH)), ValueError, "U"),
    ("linearize-U-empty", lambda: DYN.linearize(XH, np.zeros((0, NU)), MH[:0], Linearization(NH)), ValueError, "U"),
    ("linearize-U-nan", lambda: DYN.linearize(XH, _with(np.zeros((NH, NU)), 2, np.nan), MH, Linearization(NH)),
     ValueError, "U"),
    ("linearize-X-short", lambda: DYN.linearize(XH[:NH - 1], UH, MH, Linearization(NH)), ValueError, "X"),
    ("linearize-X-columns", lambda: DYN.linearize(XH[:, :NQ], UH, MH, Linearization(NH)), ValueError, "X"),
    ("linearize-X-inf", lambda: DYN.linearize(_with(XH, 1, np.inf), UH, MH, Linearization(NH)), ValueError, "X"),
    ("linearize-modes-unknown", lambda: DYN.linearize(XH, UH, np.full(NH, 7), Linearization(NH)), ValueError,
     "modes"),
    ("linearize-modes-negative", lambda: DYN.linearize(XH, UH, np.full(NH, -1), Linearization(NH)), ValueError,
     "modes"),
    ("linearize-modes-length", lambda: DYN.linearize(XH, UH, MH[:2], Linearization(NH)), ValueError, "modes"),
    ("linearize-modes-float", lambda: DYN.linearize(XH, UH, MH.astype(float), Linearization(NH)), ValueError,
     "modes"),
    ("linearize-out-capacity", lambda: DYN.linearize(XH, UH, MH, Linearization(NH - 1)), ValueError, "out"),
    ("linearize-out-type", lambda: DYN.linearize(XH, UH, MH, None), TypeError, "out"),
    ("linearize-h-negative", lambda: DYN.linearize(XH, UH, MH, Linearization(NH), -1e-3), ValueError, "h"),
    ("linearize-h-nan", lambda: DYN.linearize(XH, UH, MH, Linearization(NH), np.full(NH, np.nan)), ValueError, "h"),
    ("linearize-h-shape", lambda: DYN.linearize(XH, UH, MH, Linearization(NH), np.full(NH + 1, 1e-3)), ValueError,
     "h"),
    # references and the heuristic
    ("reference-speed-nan", lambda: end_of_mode_reference(Mode.BACK_STANCE, None, speed=math.nan), ValueError,
     "speed"),
    ("reference-speed-str", lambda: end_of_mode_reference(Mode.BACK_STANCE, None, speed="1"), ValueError, "speed"),
    ("reference-params", lambda: end_of_mode_reference(Mode.BACK_STANCE, None, params="robot"), TypeError,
     "params"),
    ("initial-state-params", lambda: paper_initial_state("robot"), TypeError, "params"),
    ("reference-touchdown-foot", lambda: end_of_mode_reference(Mode.FLIGHT, None), ValueError, "touchdown_foot"),
    ("reference-z-velocity", lambda: end_of_mode_reference(Mode.BACK_STANCE, None, z_velocity="zero"), ValueError,
     "z_velocity"),
    ("heuristic-gains", lambda: HeuristicBoundingController(ROBOT, gains={"kp": 1.0}), TypeError, "gains"),
    ("heuristic-x", lambda: HeuristicBoundingController(ROBOT).torque(X0[:10], Mode.FLIGHT), ValueError, "x"),
    # rollout
    ("rollout-dynamics", lambda: rollout("dyn", SCHEDULE, X0, controls=np.zeros((7, NU))), TypeError, "dynamics"),
    ("rollout-schedule", lambda: rollout(DYN, [2, 0], X0, controls=np.zeros((7, NU))), TypeError, "schedule"),
    ("rollout-x0-nan", lambda: rollout(DYN, SCHEDULE, _with(X0, 0, np.nan), controls=np.zeros((7, NU))), ValueError,
     "x0"),
    ("rollout-x0-shape", lambda: rollout(DYN, SCHEDULE, Q0, controls=np.zeros((7, NU))), ValueError, "x0"),
    ("rollout-controls-shape", lambda: rollout(DYN, SCHEDULE, X0, controls=np.zeros((6, NU))), ValueError, "controls"),
    ("rollout-controls-inf", lambda: rollout(DYN, SCHEDULE, X0, controls=np.full((7, NU), np.inf)), ValueError,
     "controls"),
    ("rollout-controls-type", lambda: rollout(DYN, SCHEDULE, X0, controls="zeros"), TypeError, "controls"),
    ("rollout-neither", lambda: rollout(DYN, SCHEDULE, X0), ValueError, "controls"),
    ("rollout-both", lambda: rollout(DYN, SCHEDULE, X0, controls=np.zeros((7, NU)), controller=lambda *a: U0),
     ValueError, "controller"),
    ("rollout-restitution", lambda: rollout(DYN, SCHEDULE, X0, controls=np.zeros((7, NU)), restitution=2.0),
     ValueError, "restitution"),
]

# dynamics methods: every (state, control, mode) entry point gets the same bad inputs
STEP_METHODS = ("step", "step_derivatives", "accelerations")
BAD_STEP_INPUTS = [
    ("x-short", lambda: (X0[:13], U0, 0), ValueError, "x"),
    ("x-2d", lambda: (X0[None], U0, 0), ValueError, "x"),
    ("x-nan", lambda: (_with(X0, 3, np.nan), U0, 0), ValueError, "x"),
    ("x-inf", lambda: (_with(X0, 10, -np.inf), U0, 0), ValueError, "x"),
    ("x-str", lambda: ("state", U0, 0), TypeError, "x"),
    ("u-long", lambda: (X0, np.zeros(5), 0), ValueError, "u"),
    ("u-nan", lambda: (X0, _with(U0, 1, np.nan), 0), ValueError, "u"),
    ("u-inf", lambda: (X0, _with(U0, 0, np.inf), 0), ValueError, "u"),
    ("u-none", lambda: (X0, None, 0), ValueError, "u"),
    ("mode-4", lambda: (X0, U0, 4), ValueError, "mode"),
    ("mode-negative", lambda: (X0, U0, -1), ValueError, "mode"),
    ("mode-str", lambda: (X0, U0, "FLIGHT"), ValueError, "mode"),
    ("mode-none", lambda: (X0, U0, None), ValueError, "mode"),
    ("mode-float", lambda: (X0, U0, 1.5), ValueError, "mode"),
]
for _method in STEP_METHODS:
    for _id, _args, _exc, _name in BAD_STEP_INPUTS:
        CASES.append((f"{_method}-{_id}", lambda m=_method, a=_args: getattr(DYN, m)(*a()), _exc, _name))

RESET_METHODS = ("reset_map", "reset_map_jacobian")
BAD_RESET_INPUTS = [
    ("x-short", lambda: (X0[:7], Mode.FRONT_STANCE), {}, ValueError, "x"),
    ("x-nan", lambda: (_with(X0, 8, np.nan), Mode.FRONT_STANCE), {}, ValueError, "x"),
    ("restitution-negative", lambda: (X0, Mode.FRONT_STANCE), {"restitution": -0.1}, ValueError, "restitution"),
    ("restitution-above-1", lambda: (X0, Mode.FRONT_STANCE), {"restitution": 1.5}, ValueError, "restitution"),
    ("restitution-nan", lambda: (X0, Mode.FRONT_STANCE), {"restitution": math.nan}, ValueError, "restitution"),
    ("restitution-str", lambda: (X0, Mode.FRONT_STANCE), {"restitution": "0"}, TypeError, "restitution"),
    ("restitution-bool", lambda: (X0, Mode.FRONT_STANCE), {"restitution": True}, TypeError, "restitution"),
    ("mode-unknown", lambda: (X0, 9), {}, ValueError, "mode_after"),
]
for _method in RESET_METHODS:
    for _id, _args, _kwargs, _exc, _name in BAD_RESET_INPUTS:
        CASES.append((f"{_method}-{_id}", lambda m=_method, a=_args, k=_kwargs: getattr(DYN, m)(*a(), **k), _exc,
                      _name))


@pytest.mark.parametrize(("call", "exc", "name"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_raises_an_error_naming_the_argument(call, exc, name):
    with pytest.raises(exc, match=rf"\b{name}\b"):
        call()


def test_bad_input_does_not_corrupt_later_calls():
    """A rejected call leaves the dynamics usable and its results unchanged."""
    reference = HybridDynamics(ROBOT).step(X0, U0, Mode.BACK_STANCE)
    dyn = HybridDynamics(ROBOT)
    for bad in (X0[:13], _with(X0, 0, np.nan)):
        with pytest.raises(ValueError):
            dyn.step(bad, U0, Mode.BACK_STANCE)
    result = dyn.step(X0, U0, Mode.BACK_STANCE)
    np.testing.assert_array_equal(result[0], reference[0])
    np.testing.assert_array_equal(result[1], reference[1])


def test_linearize_accepts_what_the_solver_passes():
    """Valid horizons still work after the checks: a (N,) step array, a scalar step, Mode members as modes."""
    for h in (None, 1e-3, np.full(NH, 1e-3)):
        lin = Linearization(NH + 2)
        DYN.linearize(XH, UH, MH, lin, h)
        _, _, f_x, _, _, _ = DYN.step_derivatives(X0, U0, Mode(int(MH[-1])))
        np.testing.assert_allclose(lin.f_x[NH - 1], f_x, rtol=1e-12, atol=1e-12)
    DYN.linearize(XH, UH, [Mode(int(m)) for m in MH], Linearization(NH))
    DYN.linearize(XH[:NH], UH, MH, Linearization(NH))  # only X[:N] is read


def test_controller_output_is_checked():
    with pytest.raises(ValueError, match="controller"):
        rollout(DYN, SCHEDULE, X0, controller=lambda x, mode, phase, k: np.zeros(3))


# ----------------------------------------------------------------------------------------- error messages
# Regression tests: these messages once did not name the argument (or accepted the wrong type).
@pytest.mark.parametrize("method", RESET_METHODS)
def test_reset_map_error_names_mode_after(method):
    with pytest.raises(ValueError, match="mode_after"):
        getattr(DYN, method)(X0, 9)


def test_schedule_non_numeric_durations_named():
    with pytest.raises((ValueError, TypeError), match="durations"):
        ModeSchedule([0], ["a"])


def test_bounding_non_numeric_durations_named():
    with pytest.raises((ValueError, TypeError), match="durations"):
        ModeSchedule.bounding(1, durations=["a"] * 4)


def test_bounding_unknown_start_named():
    with pytest.raises(ValueError, match="start"):
        ModeSchedule.bounding(1, start=9)


def test_reference_unknown_mode_named():
    with pytest.raises(ValueError, match=r"\bmode\b"):
        end_of_mode_reference(9, None)


@pytest.mark.parametrize("capacity", ["a", 2.7])
def test_linearization_capacity_type_checked(capacity):
    with pytest.raises((ValueError, TypeError), match="capacity"):
        Linearization(capacity)


@pytest.mark.filterwarnings("ignore::numpy.exceptions.ComplexWarning")
def test_complex_state_is_rejected():
    with pytest.raises(TypeError, match="x"):
        DYN.step(X0 + 1j, U0, Mode.FLIGHT)

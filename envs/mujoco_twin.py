"""A MuJoCo twin of ``hsddp_gym/Bounding-v0``: the same robot, task and API on an established soft-contact
simulator, registered as ``hsddp_gym/BoundingMuJoCo-v0`` (needs the optional extra ``mujoco``:
``pip install hsddp_gym[mujoco]``).

Model (:func:`build_mjcf`, from :mod:`hsddp_gym.core.params`)
-------------------------------------------------------------
One ``trunk`` body carrying the joints ``x`` (slide along x), ``z`` (slide along z) and ``pitch`` (hinge about
+y, positive nose-down) in that order -- the chain of the Pinocchio model -- and two legs of a ``thigh`` (hip
hinge at ``(+-hip_offset, 0, 0)``) and a ``shank`` (knee hinge ``thigh.length`` below the hip); every body's
mass, CoM (``com_z`` along the link) and ``I_yy`` come from :class:`~hsddp_gym.core.params.RobotParams`
(``diaginertia = I_yy (1, 1, 1)`` as in the Pinocchio model; off-plane axes cannot act), with
``inertiafromgeom="false"`` so that geoms add no mass; no armature, damping or joint limits. The point foot is a
sphere of radius :data:`FOOT_RADIUS` centred on the foot point, and the floor plane lies ``FOOT_RADIUS`` below
``z = 0``, so a foot touches exactly when the foot point reaches ``z = 0`` (the env's ground). Only the feet
collide, with the floor. Joint torques enter as ``qfrc_applied`` (the motors' torque-speed limit of the env is
applied first, the same code).

Simulation: ``timestep`` 1 ms, MuJoCo's semi-implicit ``Euler`` integrator, elliptic friction cone with
``mu`` = 0.6, and a stiff soft contact ``solref = (0.005, 1)`` (5 ms time constant, critically damped; MuJoCo's
default is 0.02 s) with the default ``solimp``. Unlike the exact-LCP env, contacts are compliant: feet sink
millimetres, may bounce and slip slightly while "sticking".

Divergence: when MuJoCo meets a non-finite or huge ``qpos``/``qvel``/``qacc`` it warns and silently resets the
state to ``qpos0``; the twin turns that into a non-finite state, so the env reports ``info["invalid_state"]``
exactly as Bounding-v0 does.

Checks (``tests/test_mujoco_twin.py``): mass matrix, bias forces (Coriolis + gravity) and foot positions equal
the Pinocchio model's to 1e-9 at random states, and a free-flight step equals the legacy Bounding-v0 step (the
same semi-implicit Euler) to 1e-9.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.contact import SimulatorQueries
from hsddp_gym.core.conventions import FEET, FOOT_NAMES, FOOT_SIGN, NQ, NX
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.params import DEFAULT_PARAMS, RobotParams
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.util.validation import check_positive, check_vector

FOOT_RADIUS = 0.005
"""Radius [m] of the foot spheres; the floor is this far below z = 0 (contact when the foot point reaches 0)."""
DEFAULT_SOLREF = (0.005, 1.0)
"""MuJoCo contact ``solref`` (time constant [s], damping ratio): stiff and critically damped."""
JOINT_NAMES = ("x", "z", "pitch", "hip_front", "knee_front", "hip_back", "knee_back")


def _import_mujoco():
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImportError("the MuJoCo twin needs the optional extra: pip install 'hsddp_gym[mujoco]'") from exc
    return mujoco


def build_mjcf(params: RobotParams = DEFAULT_PARAMS, timestep: float = 1e-3, friction: float | None = None,
               gravity: float | None = None, solref=DEFAULT_SOLREF) -> str:
    """The MJCF (XML string) of the planar Mini Cheetah; see the module docstring.

    Args:
        params: the robot. timestep: [s]. friction: Coulomb ``mu`` (default ``params.friction``).
        gravity: [m/s^2] (default ``params.gravity``). solref: contact ``(time constant [s], damping ratio)``.
    """
    if not isinstance(params, RobotParams):
        raise TypeError(f"params must be a RobotParams, got {type(params).__name__}")
    timestep = check_positive(timestep, "timestep")
    mu = check_positive(params.friction if friction is None else friction, "friction", allow_zero=True)
    g = check_positive(params.gravity if gravity is None else gravity, "gravity", allow_zero=True)
    ref = [float(s) for s in check_vector(solref, 2, "solref")]
    if not ref[0] > 0.0 or not ref[1] > 0.0:
        raise ValueError(f"solref must hold a positive time constant and damping ratio, got {solref!r}")

    def inertial(link) -> str:
        i = link.inertia_yy
        return f'<inertial pos="0 0 {link.com_z!r}" mass="{link.mass!r}" diaginertia="{i!r} {i!r} {i!r}"/>'

    legs = []
    for foot in FEET:
        name = FOOT_NAMES[foot]
        legs.append(f'''
      <body name="thigh_{name}" pos="{FOOT_SIGN[foot] * params.hip_offset!r} 0 0">
        <joint name="hip_{name}" type="hinge" axis="0 1 0"/>
        {inertial(params.thigh)}
        <geom type="capsule" fromto="0 0 0 0 0 {-params.thigh.length!r}" size="0.01" contype="0" conaffinity="0"/>
        <body name="shank_{name}" pos="0 0 {-params.thigh.length!r}">
          <joint name="knee_{name}" type="hinge" axis="0 1 0"/>
          {inertial(params.shank)}
          <geom type="capsule" fromto="0 0 0 0 0 {-params.shank.length!r}" size="0.008" contype="0"
                conaffinity="0"/>
          <geom name="foot_{name}" type="sphere" pos="0 0 {-params.shank.length!r}" size="{FOOT_RADIUS!r}"
                contype="1" conaffinity="0" condim="3" friction="{mu!r} 0 0" solref="{ref[0]!r} {ref[1]!r}"/>
          <site name="foot_{name}" pos="0 0 {-params.shank.length!r}"/>
        </body>
      </body>''')
    return f'''<mujoco model="planar_mini_cheetah">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{timestep!r}" gravity="0 0 {-g!r}" integrator="Euler" cone="elliptic"/>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" pos="0 0 {-FOOT_RADIUS!r}" contype="0" conaffinity="1"
          condim="3" friction="{mu!r} 0 0" solref="{ref[0]!r} {ref[1]!r}"/>
    <body name="trunk">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <joint name="pitch" type="hinge" axis="0 1 0"/>
      {inertial(params.trunk)}
      <geom type="box" size="{params.hip_offset!r} 0.05 0.03" contype="0" conaffinity="0"/>{"".join(legs)}
    </body>
  </worldbody>
</mujoco>
'''


class MuJoCoSimulator(SimulatorQueries):
    """The MuJoCo model behind the interface :class:`~hsddp_gym.envs.bounding.BoundingEnv` uses of
    :class:`~hsddp_gym.envs.contact.ContactSimulator` (``x``/``q``/``v`` views, ``set_state``, ``run``,
    ``contact``, ``impulse``, ``foot_heights_fast``, ``energy``, ...).

    Args:
        robot: the model (default: the paper's robot). timestep, friction, gravity: as ContactSimulator.
        motor_speed_limits: with ``torque_limit``, the env's torque-speed limit (same semantics).
        torque_limit: see ``motor_speed_limits``.
        solref: MuJoCo contact ``solref`` (default :data:`DEFAULT_SOLREF`).
    """

    def __init__(self, robot: CheetahModel | None = None, timestep: float = 1e-3, friction: float | None = None,
                 gravity: float | None = None, motor_speed_limits=None, torque_limit: float | None = None,
                 solref=DEFAULT_SOLREF) -> None:
        mujoco = _import_mujoco()
        self._mj = mujoco
        self.robot = self._set_common(robot, timestep, friction, gravity, torque_limit, motor_speed_limits)
        params = self.robot.params
        self.xml = build_mjcf(params, self.dt, self.mu, self.gravity, solref)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self._foot_geoms = tuple(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, f"foot_{FOOT_NAMES[f]}")
                                 for f in FEET)
        self._foot_sites = tuple(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, f"foot_{FOOT_NAMES[f]}")
                                 for f in FEET)
        # pinocchio-side helpers for energy / diagnostics
        import pinocchio as pin

        self._pin = pin
        self._pmodel = pin.Model(self.robot.model)
        self._pmodel.gravity = pin.Motion(np.array([0.0, 0.0, -self.gravity]), np.zeros(3))
        self._pdata = self._pmodel.createData()
        self.x = np.zeros(NX)
        self.q = self.x[:NQ]
        self.v = self.x[NQ:]
        self.time = 0.0
        self.impulse = np.zeros(4)
        self.contact = np.zeros(2, dtype=bool)
        self.states = [0, 0]
        self.lcp_fallbacks = 0
        self._f6 = np.zeros(6)
        self._imp_sum = [0.0, 0.0, 0.0, 0.0]
        w = mujoco.mjtWarning
        self._unstable = (int(w.mjWARN_BADQPOS), int(w.mjWARN_BADQVEL), int(w.mjWARN_BADQACC))
        self._seen_instabilities = 0

    def _instabilities(self) -> int:
        """How many times MuJoCo has warned of a non-finite / huge qpos, qvel or qacc (it then resets the state)."""
        warning = self.data.warning
        return sum(warning[i].number for i in self._unstable)

    def set_state(self, x: np.ndarray) -> None:
        """Set the state ``x`` (14,), reset the clock and contact flags."""
        self.x[:] = check_vector(x, NX, "x")
        self.time = 0.0
        self.impulse[:] = 0.0
        self.contact[:] = False
        self._mj.mj_resetData(self.model, self.data)
        self._seen_instabilities = 0
        self._load()
        self._mj.mj_forward(self.model, self.data)

    def _load(self) -> None:
        self.data.qpos[:] = self.q
        self.data.qvel[:] = self.v

    def energy(self) -> float:
        """Mechanical energy [J] of the current state (Pinocchio, this world's gravity)."""
        pin = self._pin
        return float(pin.computeKineticEnergy(self._pmodel, self._pdata, self.q, self.v)
                     + pin.computePotentialEnergy(self._pmodel, self._pdata, self.q))

    def run(self, u: np.ndarray, n: int) -> list:
        """``n`` MuJoCo steps with commanded joint torques ``u`` (4,).

        Returns:
            The summed ground impulses over the ``n`` steps, grf layout (list of 4 floats) [N s].
        """
        mj, model, data = self._mj, self.model, self.data
        total = self._imp_sum
        total[0] = total[1] = total[2] = total[3] = 0.0
        self._load()  # the env may have pushed (changed v) since the last call
        h = self.dt
        u = np.asarray(u, dtype=np.float64)
        for _ in range(n):
            if self.motor_speed_limits is None:
                data.qfrc_applied[3:] = u
            else:
                self.x[NQ:] = data.qvel
                data.qfrc_applied[3:] = self.applied_torque(u)
            mj.mj_step(model, data)
            self._contact_forces()
            for k in range(4):
                total[k] += self.impulse[k] * h
        self.x[:NQ] = data.qpos
        self.x[NQ:] = data.qvel
        if self._instabilities() != self._seen_instabilities:
            # MuJoCo met a non-finite or huge qpos/qvel/qacc and silently reset the state to qpos0: report it
            # as what it is, an invalid state (the env then sets info["invalid_state"] and stops stepping)
            self._seen_instabilities = self._instabilities()
            self.x[:] = np.nan
        self.time += n * h
        # impulse: of the last step [N s], as ContactSimulator
        self.impulse *= h
        return total

    def _contact_forces(self) -> None:
        """Ground forces on the feet (grf layout, [N]) and contact flags of the last MuJoCo step."""
        mj, model, data = self._mj, self.model, self.data
        force = self.impulse
        force[:] = 0.0
        self.contact[:] = False
        f6 = self._f6
        for i in range(data.ncon):
            c = data.contact[i]
            for foot, gid in zip(FEET, self._foot_geoms):
                if c.geom1 == gid or c.geom2 == gid:
                    mj.mj_contactForce(model, data, i, f6)
                    world = c.frame.reshape(3, 3).T @ f6[:3]  # force of geom1 on geom2, world frame
                    if c.geom1 == gid:
                        world = -world
                    force[2 * foot] += world[0]
                    force[2 * foot + 1] += world[2]
                    if f6[0] > 1e-9:
                        self.contact[foot] = True


class MuJoCoBoundingEnv(BoundingEnv):
    """``hsddp_gym/BoundingMuJoCo-v0``: :class:`~hsddp_gym.envs.bounding.BoundingEnv` (same observation, action,
    reward, reset, termination, info and arguments) simulated by MuJoCo (:class:`MuJoCoSimulator`) instead of the
    exact-LCP contact simulator. Extra argument ``solref`` (the MuJoCo contact's ``(time constant, damping
    ratio)``, default (0.005, 1)); ``contact_erp`` and ``energy_consistent`` do not apply (accepted, ignored).
    Contact flags are set when MuJoCo reports a positive normal force on the foot in the last 1 ms step."""

    def __init__(self, *args, solref=DEFAULT_SOLREF, **kwargs) -> None:
        self._solref = tuple(float(s) for s in check_vector(solref, 2, "solref"))
        super().__init__(*args, **kwargs)

    def _make_simulator(self, friction, gravity, contact_erp, motor_speed_limits, energy_consistent):
        return MuJoCoSimulator(self.robot, timestep=self.sim_timestep, friction=friction, gravity=gravity,
                               motor_speed_limits=motor_speed_limits, torque_limit=self.torque_limit,
                               solref=self._solref)

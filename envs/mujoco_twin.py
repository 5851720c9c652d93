"""A MuJoCo twin of ``hsddp_gym/Bounding-v0``: the same robot, task and API on an established soft-contact
simulator, registered as ``hsddp_gym/BoundingMuJoCo-v0`` (needs the optional extra ``mujoco``:
``pip install hsddp_gym[mujoco]``), and a family of contact models to test a policy on ([`ContactModel`][ContactModel]).

Model ([`build_mjcf`][build_mjcf], from [`hsddp_gym.core.params`][hsddp_gym.core.params])
-------------------------------------------------------------
One ``trunk`` body carrying the joints ``x`` (slide along x), ``z`` (slide along z) and ``pitch`` (hinge about
+y, positive nose-down) in that order -- the chain of the Pinocchio model -- and two legs of a ``thigh`` (hip
hinge at ``(+-hip_offset, 0, 0)``) and a ``shank`` (knee hinge ``thigh.length`` below the hip); every body's
mass, CoM (``com_z`` along the link) and ``I_yy`` come from [`RobotParams`][hsddp_gym.core.params.RobotParams]
(``diaginertia = I_yy (1, 1, 1)`` as in the Pinocchio model; off-plane axes cannot act), with
``inertiafromgeom="false"`` so that geoms add no mass; no armature, damping or joint limits. The point foot is a
sphere of radius ``foot_radius`` (default [`FOOT_RADIUS`][FOOT_RADIUS], 5 mm) centred on the foot point, and the floor
plane lies ``foot_radius`` below ``z = 0``, so a foot touches exactly when the foot point reaches ``z = 0`` (the env's
ground). Only the feet collide, with the floor. Joint torques enter as ``qfrc_applied`` (the motors' torque-speed
limit of the env is applied first, the same code).

Terrain (``terrain=``, as Bounding-v0's): the floor plane is replaced by one box per piece of the terrain's
simulated surface ([`surface_vertices`][hsddp_gym.core.terrain.Terrain.surface_vertices],
[`terrain_geoms`][terrain_geoms]), each tilted to its piece's slope with its top face ``foot_radius`` below the piece
along its normal, so a foot sphere touches a piece when the foot point reaches it (at a corner between pieces, to within
the foot radius times the angle between them).

Simulation (the default [`ContactModel`][ContactModel]): ``timestep`` 1 ms, MuJoCo's semi-implicit ``Euler`` integrator,
elliptic friction cone with ``mu`` = 0.6, and a stiff soft contact ``solref = (0.005, 1)`` (5 ms time constant,
critically damped; MuJoCo's default is 0.02 s) with MuJoCo's default ``solimp`` and ``impratio``. Unlike the
exact-LCP env, contacts are compliant: feet sink millimetres, may bounce and slip slightly while "sticking".

Contact models
--------------
[`ContactModel`][ContactModel] (frozen, validated) is one contact model of the twin: friction cone, ``solref``,
``solimp``, foot radius, ``impratio``, time step and friction. [`ContactModel.DEFAULT`][ContactModel] is the model
above (its MJCF is the twin's, byte for byte); [`ContactModel.sample`][ContactModel.sample] draws one from the
documented family ([`FAMILY_RANGES`][FAMILY_RANGES]); [`CONTACT_CORNERS`][CONTACT_CORNERS] names the family's corners.
The env takes a model as ``contact_model=`` (a [`ContactModel`][ContactModel], a dict of its fields or a corner name)
and each field as its own keyword. The control period stays 5 ms whatever the time step: the time step must divide it
(``timestep = 5 ms / n``, ``n`` = 3..10) and the env's ``frame_skip`` defaults to ``n``.

Divergence: when MuJoCo meets a non-finite or huge ``qpos``/``qvel``/``qacc`` it warns and silently resets the
state to ``qpos0``; the twin turns that into a non-finite state, so the env reports ``info["invalid_state"]``
exactly as Bounding-v0 does.

Checks (``tests/test_mujoco_twin.py``, ``tests/test_contact_family.py``): mass matrix, bias forces (Coriolis +
gravity) and foot positions equal the Pinocchio model's to 1e-9 at random states, a free-flight step equals the
legacy Bounding-v0 step (the same semi-implicit Euler) to 1e-9, the default contact model gives the twin's MJCF and
trajectory bit for bit, and a robot dropped in every corner model lands and stands.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

import numpy as np

from hsddp_gym.core.contact import SimulatorQueries
from hsddp_gym.core.conventions import FEET, FOOT_NAMES, FOOT_SIGN, NQ, NX
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.params import DEFAULT_PARAMS, RobotParams
from hsddp_gym.core.terrain import check_terrain
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.util.validation import check_positive, check_vector

FOOT_RADIUS = 0.005
"""Radius [m] of the foot spheres of the default model; the floor is this far below z = 0 (contact when the foot
point reaches 0)."""
DEFAULT_SOLREF = (0.005, 1.0)
"""MuJoCo contact ``solref`` (time constant [s], damping ratio) of the default model: stiff and critically damped."""
MUJOCO_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
"""MuJoCo's default ``solimp`` ``(d_min, d_max, width [m], midpoint, power)``, the default model's."""
MUJOCO_IMPRATIO = 1.0
"""MuJoCo's default ``impratio`` (ratio of frictional to normal constraint impedance, elliptic cones)."""
CONTROL_PERIOD = 0.005
"""The env's control period [s]; a contact model's time step divides it."""
JOINT_NAMES = ("x", "z", "pitch", "hip_front", "knee_front", "hip_back", "knee_back")

FAMILY_RANGES = {
    "cone": ("pyramidal", "elliptic"),
    "solref_time_constant": (0.002, 0.020),
    "solref_damping_ratio": (0.5, 2.0),
    "solimp_d_min": (0.8, 0.95),
    "solimp_d_max": (0.95, 0.99),
    "solimp_width": (0.0005, 0.005),
    "foot_radius": (0.001, 0.020),
    "impratio": (1.0, 10.0),
    "timestep": (0.0005, 0.002),
    "friction": (0.4, 1.0),
}
"""The ranges of the contact-model family: [`ContactModel.sample`][ContactModel.sample] draws from them (see there for
the distribution). Units: s, m; the damping ratio, ``d`` and ``impratio`` have none."""
ACCEPTED_RANGES = {
    "solref_time_constant": (0.0005, 0.1),
    "solref_damping_ratio": (0.1, 10.0),
    "solimp_d": (0.01, 0.9999),
    "solimp_width": (1e-5, 0.05),
    "foot_radius": (0.0005, 0.05),
    "impratio": (1.0, 100.0),
    "timestep_divisions": (1, 20),
    "friction": (0.01, 2.0),
}
"""The values a [`ContactModel`][ContactModel] accepts, wider than the family's ([`FAMILY_RANGES`][FAMILY_RANGES]) so
that a user can build a model outside it (e.g. ``friction=0.3``): ``solimp``'s ``d_min`` and ``d_max`` in ``solimp_d``,
its midpoint in (0, 1) and power >= 1, the time step ``5 ms / n`` for a whole ``n`` in ``timestep_divisions``. Units: s,
m."""


def _real(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    return float(value)


def _in(value, lo: float, hi: float, name: str, unit: str = "") -> float:
    v = _real(value, name)
    if not lo <= v <= hi:
        raise ValueError(f"{name} must be in [{lo:g}, {hi:g}]{unit}, got {value!r}")
    return v


def _numbers(value, size: int, name: str) -> tuple:
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != size:
        raise ValueError(f"{name} must be {size} numbers, got {value!r}")
    return tuple(_real(v, f"{name}[{i}]") for i, v in enumerate(value))


@dataclasses.dataclass(frozen=True)
class ContactModel:
    """One contact model of the MuJoCo twin (validated on construction; ``ValueError`` naming the field, its range
    and the value received). ``ContactModel.DEFAULT`` is the twin's model, bit for bit.

    Attributes:
        cone: MuJoCo's friction cone, ``"elliptic"`` (default) or ``"pyramidal"``.
        solref: ``(time constant [s], damping ratio)`` of the soft contact: time constant in [0.5, 100] ms (default
            5 ms; MuJoCo raises a time constant below two time steps to two time steps), damping ratio in
            [0.1, 10] (default 1, critically damped).
        solimp: MuJoCo's impedance shape ``(d_min, d_max, width [m], midpoint, power)`` (default MuJoCo's
            [`MUJOCO_SOLIMP`][MUJOCO_SOLIMP]): ``d_min <= d_max`` in [0.01, 0.9999], ``width`` in [0.01, 50] mm,
            ``midpoint`` in (0, 1), ``power`` >= 1.
        foot_radius: radius [m] of the foot spheres, in [0.5, 50] mm (default 5 mm); the floor lies ``foot_radius``
            below ``z = 0`` so a foot touches when its foot point reaches the ground. A larger sphere rolls: its
            contact point moves along the ground as the shank turns.
        impratio: MuJoCo's ratio of frictional to normal impedance, in [1, 100] (default 1; elliptic cones only).
        timestep: MuJoCo's step [s]: ``5 ms / n`` for a whole ``n`` from 1 to 20 (0.25 to 5 ms; default 1 ms), so
            that the 5 ms control period is ``n`` steps ([`frame_skip`][frame_skip]); stored as exactly ``0.005 / n``.
        friction: Coulomb coefficient ``mu`` of feet and floor, in [0.01, 2] (default 0.6, the planner's model).

    The accepted ranges ([`ACCEPTED_RANGES`][ACCEPTED_RANGES]) are wider than the family's
    ([`FAMILY_RANGES`][FAMILY_RANGES]), which [`sample`][sample] draws from.
    """

    cone: str = "elliptic"
    solref: tuple = DEFAULT_SOLREF
    solimp: tuple = MUJOCO_SOLIMP
    foot_radius: float = FOOT_RADIUS
    impratio: float = MUJOCO_IMPRATIO
    timestep: float = 0.001
    friction: float = 0.6

    def __post_init__(self) -> None:
        r = ACCEPTED_RANGES
        if not isinstance(self.cone, str) or self.cone not in FAMILY_RANGES["cone"]:
            raise ValueError(f"cone must be one of {FAMILY_RANGES['cone']}, got {self.cone!r}")
        tc, dr = _numbers(self.solref, 2, "solref")
        _in(tc, *r["solref_time_constant"], "solref[0] (time constant)", " s")
        _in(dr, *r["solref_damping_ratio"], "solref[1] (damping ratio)")
        imp = _numbers(self.solimp, 5, "solimp")
        _in(imp[0], *r["solimp_d"], "solimp[0] (d_min)")
        _in(imp[1], *r["solimp_d"], "solimp[1] (d_max)")
        _in(imp[2], *r["solimp_width"], "solimp[2] (width)", " m")
        if imp[0] > imp[1]:
            raise ValueError(f"solimp must have d_min <= d_max, got {self.solimp!r}")
        if not 0.0 < imp[3] < 1.0:
            raise ValueError(f"solimp[3] (midpoint) must be in (0, 1), got {self.solimp!r}")
        if not imp[4] >= 1.0:
            raise ValueError(f"solimp[4] (power) must be >= 1, got {self.solimp!r}")
        radius = _in(self.foot_radius, *r["foot_radius"], "foot_radius", " m")
        impratio = _in(self.impratio, *r["impratio"], "impratio")
        lo, hi = r["timestep_divisions"]
        h = _in(self.timestep, CONTROL_PERIOD / hi, CONTROL_PERIOD / lo, "timestep", " s")
        n = round(CONTROL_PERIOD / h)
        if abs(CONTROL_PERIOD / h - n) > 1e-6 * n:
            raise ValueError(f"timestep must divide the 5 ms control period (5 ms / n, n = {lo}..{hi}), got "
                             f"{self.timestep!r}")
        mu = _in(self.friction, *r["friction"], "friction")
        for name, value in (("solref", (tc, dr)), ("solimp", imp), ("foot_radius", radius), ("impratio", impratio),
                            ("timestep", CONTROL_PERIOD / n), ("friction", mu)):
            object.__setattr__(self, name, value)

    @property
    def frame_skip(self) -> int:
        """MuJoCo steps per 5 ms control period (``5 ms / timestep``)."""
        return round(CONTROL_PERIOD / self.timestep)

    def as_dict(self) -> dict:
        """The fields as a JSON-serializable dict (tuples as lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}

    def replace(self, **changes) -> ContactModel:
        """A copy with ``changes`` (field names; validated)."""
        fields = [f.name for f in dataclasses.fields(self)]
        unknown = sorted(set(changes) - set(fields))
        if unknown:
            raise TypeError(f"unknown ContactModel field(s) {unknown}; fields: {fields}")
        return dataclasses.replace(self, **changes)

    @classmethod
    def parse(cls, value, name: str = "contact_model") -> ContactModel:
        """``value`` as a model: a [`ContactModel`][ContactModel], a dict of its fields (missing ones: the default's) or
        the name of a corner of [`CONTACT_CORNERS`][CONTACT_CORNERS]; ``TypeError``/``ValueError`` naming ``name``
        otherwise."""
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            if value not in CONTACT_CORNERS:
                raise ValueError(f"{name} must be a ContactModel, a dict of its fields or one of the corners "
                                 f"{list(CONTACT_CORNERS)}, got {value!r}")
            return CONTACT_CORNERS[value]
        if isinstance(value, dict):
            fields = {f.name for f in dataclasses.fields(cls)}
            unknown = sorted(set(value) - fields)
            if unknown:
                raise ValueError(f"{name}: unknown field(s) {unknown}; allowed: {sorted(fields)}")
            return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in value.items()})
        raise TypeError(f"{name} must be a ContactModel, a dict of its fields or a corner name, got "
                        f"{type(value).__name__}")

    @classmethod
    def sample(cls, rng: np.random.Generator) -> ContactModel:
        """One model of the family, drawn from ``rng`` in this order (every draw made, so the sequence of draws
        does not depend on the values):

        * ``cone``: pyramidal or elliptic, probability 1/2 each;
        * ``solref``: time constant log-uniform in [2, 20] ms, damping ratio log-uniform in [0.5, 2];
        * ``solimp``: ``d_min`` uniform in [0.8, 0.95], ``d_max`` uniform in [0.95, 0.99], ``width``
          log-uniform in [0.5, 5] mm, midpoint 0.5 and power 2 (MuJoCo's);
        * ``foot_radius``: log-uniform in [1, 20] mm;
        * ``impratio``: log-uniform in [1, 10];
        * ``timestep``: ``5 ms / n``, ``n`` uniform in {3, ..., 10} (1.667 ms to 0.5 ms);
        * ``friction``: uniform in [0.4, 1].
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        r = FAMILY_RANGES

        def log_uniform(lo: float, hi: float) -> float:
            return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

        cone = r["cone"][int(rng.integers(2))]
        solref = (log_uniform(*r["solref_time_constant"]), log_uniform(*r["solref_damping_ratio"]))
        solimp = (float(rng.uniform(*r["solimp_d_min"])), float(rng.uniform(*r["solimp_d_max"])),
                  log_uniform(*r["solimp_width"]), 0.5, 2.0)
        foot_radius = log_uniform(*r["foot_radius"])
        impratio = log_uniform(*r["impratio"])
        timestep = CONTROL_PERIOD / int(rng.integers(3, 11))
        friction = float(rng.uniform(*r["friction"]))
        return cls(cone, solref, solimp, foot_radius, impratio, timestep, friction)


ContactModel.DEFAULT = ContactModel()  # type: ignore[attr-defined]
"""The twin's contact model (its MJCF and trajectories are the twin's, bit for bit)."""

CONTACT_CORNERS: dict[str, ContactModel] = {
    "softest": ContactModel(solref=(0.020, 0.5)),
    "stiffest": ContactModel(solref=(0.002, 1.0)),
    "pyramidal": ContactModel(cone="pyramidal"),
    "large_feet": ContactModel(foot_radius=0.020),
    "low_friction": ContactModel(friction=0.4),
    "coarse_step": ContactModel(timestep=CONTROL_PERIOD / 3),
}
"""Named corners of the contact-model family, each the default model with one setting at the end of its range:
``softest`` (``solref = (20 ms, 0.5)``: the slowest, least damped contact, springy and deep), ``stiffest``
(``solref = (2 ms, 1)``, at the 1 ms step the stiffest MuJoCo allows), ``pyramidal`` (pyramidal friction cone),
``large_feet`` (20 mm foot spheres, which roll), ``low_friction`` (``mu = 0.4``; the planner assumes 0.6) and
``coarse_step`` (``timestep = 5/3 ms``, three steps per control period)."""


def _resolve(contact_model, friction_default: float | None = None, **fields) -> ContactModel:
    """``contact_model`` (see [`ContactModel.parse`][ContactModel.parse]; None: the default, with ``friction_default``
    when given) with the non-None ``fields`` replacing its own (validated)."""
    if contact_model is None:
        base = ContactModel.DEFAULT
        if friction_default is not None and fields.get("friction") is None:
            fields["friction"] = friction_default
    else:
        base = ContactModel.parse(contact_model)
    changes = {k: v for k, v in fields.items() if v is not None}
    return base.replace(**changes) if changes else base


def _import_mujoco():
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImportError("the MuJoCo twin needs the optional extra: pip install 'hsddp_gym[mujoco]'") from exc
    return mujoco


TERRAIN_BOX_THICKNESS = 0.1
"""Thickness [m] of the boxes that make a terrain's surface in the MJCF ([`terrain_geoms`][terrain_geoms])."""


def terrain_geoms(terrain, foot_radius: float, friction: float, solref, imp: str = "") -> str:
    """The MJCF ``<geom>`` boxes of ``terrain``'s simulated surface (one per piece between consecutive vertices of
    [`surface_vertices`][hsddp_gym.core.terrain.Terrain.surface_vertices]), named ``terrain_0``, ``terrain_1``, ...: a
    box as long as its piece, tilted about +y to its slope, [`TERRAIN_BOX_THICKNESS`][TERRAIN_BOX_THICKNESS] thick, its
    top face ``foot_radius`` below the piece along the piece's normal."""
    xs, zs = terrain.surface_vertices()
    out = []
    half_t = 0.5 * TERRAIN_BOX_THICKNESS
    for i in range(len(xs) - 1):
        dx, dz = float(xs[i + 1] - xs[i]), float(zs[i + 1] - zs[i])
        length = math.hypot(dx, dz)
        nx, nz = -dz / length, dx / length  # the piece's outward normal
        cx = 0.5 * float(xs[i] + xs[i + 1]) - (foot_radius + half_t) * nx
        cz = 0.5 * float(zs[i] + zs[i + 1]) - (foot_radius + half_t) * nz
        angle = math.atan2(dz, dx)  # a rotation by -angle about +y lifts the box's x axis to the piece's direction
        out.append(f'\n    <geom name="terrain_{i}" type="box" size="{0.5 * length!r} 1 {half_t!r}" '
                   f'pos="{cx!r} 0 {cz!r}"\n          axisangle="0 1 0 {-angle!r}" contype="0" conaffinity="1" '
                   f'condim="3" friction="{friction!r} 0 0" solref="{solref[0]!r} {solref[1]!r}"{imp}/>')
    return "".join(out)


def build_mjcf(params: RobotParams = DEFAULT_PARAMS, timestep: float | None = None, friction: float | None = None,
               gravity: float | None = None, solref=None, *, cone: str | None = None, solimp=None,
               foot_radius: float | None = None, impratio: float | None = None, contact_model=None,
               terrain=None) -> str:
    """The MJCF (XML string) of the planar Mini Cheetah; see the module docstring.

    Args:
        params: the robot. gravity: [m/s^2] (default ``params.gravity``).
        timestep: MuJoCo's step [s] (5 ms / n); replaces ``contact_model``'s (None: keep it). Every contact argument
            below likewise replaces that field of ``contact_model`` and is validated as [`ContactModel`][ContactModel].
        friction: Coulomb ``mu`` (in [0.01, 2]).
        solref: ``(time constant [s], damping ratio)``.
        cone: ``"elliptic"`` or ``"pyramidal"``.
        solimp: ``(d_min, d_max, width [m], midpoint, power)``.
        foot_radius: [m].
        impratio: frictional / normal impedance ratio.
        contact_model: a [`ContactModel`][ContactModel] (or a dict of its fields, or a corner name); None: the default
            model with ``params.friction``.
        terrain: a [`Terrain`][hsddp_gym.core.terrain.Terrain] (its surface as boxes, [`terrain_geoms`][terrain_geoms])
            or None (the floor plane).

    The ``solimp`` and ``impratio`` attributes are written only when they differ from MuJoCo's defaults, so the
    default model's XML is the twin's original one, byte for byte.
    """
    if not isinstance(params, RobotParams):
        raise TypeError(f"params must be a RobotParams, got {type(params).__name__}")
    cm = _resolve(contact_model, params.friction, timestep=timestep, friction=friction, solref=solref, cone=cone,
                  solimp=solimp, foot_radius=foot_radius, impratio=impratio)
    g = check_positive(params.gravity if gravity is None else gravity, "gravity", allow_zero=True)
    mu, ref, radius = cm.friction, cm.solref, cm.foot_radius
    imp = "" if cm.solimp == MUJOCO_SOLIMP else ' solimp="' + " ".join(repr(v) for v in cm.solimp) + '"'
    impratio_attr = "" if cm.impratio == MUJOCO_IMPRATIO else f' impratio="{cm.impratio!r}"'

    if terrain is None:
        floor = (f'\n    <geom name="floor" type="plane" size="0 0 1" pos="0 0 {-radius!r}" contype="0" conaffinity="1"'
                 f'\n          condim="3" friction="{mu!r} 0 0" solref="{ref[0]!r} {ref[1]!r}"{imp}/>')
    else:
        floor = terrain_geoms(check_terrain(terrain), radius, mu, ref, imp)

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
          <geom name="foot_{name}" type="sphere" pos="0 0 {-params.shank.length!r}" size="{radius!r}"
                contype="1" conaffinity="0" condim="3" friction="{mu!r} 0 0" solref="{ref[0]!r} {ref[1]!r}"{imp}/>
          <site name="foot_{name}" pos="0 0 {-params.shank.length!r}"/>
        </body>
      </body>''')
    return f'''<mujoco model="planar_mini_cheetah">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{cm.timestep!r}" gravity="0 0 {-g!r}" integrator="Euler" cone="{cm.cone}"{impratio_attr}/>
  <worldbody>{floor}
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
    """The MuJoCo model behind the interface [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] uses of
    [`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] (``x``/``q``/``v`` views, ``set_state``, ``run``,
    ``contact``, ``impulse``, ``foot_heights_fast``, ``energy``, ...).

    Args:
        robot: the model (default: the paper's robot). gravity: as ContactSimulator.
        motor_speed_limits: with ``torque_limit``, the env's torque-speed limit (same semantics).
        torque_limit: see ``motor_speed_limits``.
        contact_model: the contact model (a [`ContactModel`][ContactModel], a dict of its fields or a corner name of
            [`CONTACT_CORNERS`][CONTACT_CORNERS]; None: [`ContactModel.DEFAULT`][ContactModel] with the robot's
            friction).
        timestep: MuJoCo's step [s] (5 ms / n). This and every contact argument below replace that field of
            ``contact_model`` (None: keep it), validated as [`ContactModel`][ContactModel] (``ValueError`` naming the
            argument).
        friction: Coulomb ``mu`` (in [0.01, 2]).
        solref: ``(time constant [s], damping ratio)``.
        cone: ``"elliptic"`` or ``"pyramidal"``.
        solimp: ``(d_min, d_max, width [m], midpoint, power)``.
        foot_radius: [m].
        impratio: frictional / normal impedance ratio.

    Attributes:
        contact_model: the [`ContactModel`][ContactModel] simulated. dt: its time step [s]. mu: its friction.
    """

    def __init__(self, robot: CheetahModel | None = None, timestep: float | None = None, friction: float | None = None,
                 gravity: float | None = None, motor_speed_limits=None, torque_limit: float | None = None,
                 solref=None, *, cone: str | None = None, solimp=None, foot_radius: float | None = None,
                 impratio: float | None = None, contact_model=None, terrain=None) -> None:
        mujoco = _import_mujoco()
        self._mj = mujoco
        params = (robot.params if isinstance(robot, CheetahModel) else DEFAULT_PARAMS)
        self.contact_model = _resolve(contact_model, params.friction, timestep=timestep, friction=friction,
                                      solref=solref, cone=cone, solimp=solimp, foot_radius=foot_radius,
                                      impratio=impratio)
        cm = self.contact_model
        self.robot = self._set_common(robot, cm.timestep, cm.friction, gravity, torque_limit, motor_speed_limits)
        self.terrain = check_terrain(terrain)
        self._build()
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

    def _build(self) -> None:
        """The MuJoCo model and data of the robot, the contact model and the terrain."""
        mujoco = self._mj
        self.xml = build_mjcf(self.robot.params, gravity=self.gravity, contact_model=self.contact_model,
                              terrain=self.terrain)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self._foot_geoms = tuple(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, f"foot_{FOOT_NAMES[f]}")
                                 for f in FEET)
        self._foot_sites = tuple(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, f"foot_{FOOT_NAMES[f]}")
                                 for f in FEET)

    def set_terrain(self, terrain) -> None:
        """Simulate on ``terrain`` (a [`Terrain`][hsddp_gym.core.terrain.Terrain] or None: the floor plane): the MuJoCo
        model is rebuilt when it changes (set a state before stepping again)."""
        terrain = check_terrain(terrain)
        if terrain == self.terrain:
            return
        self.terrain = terrain
        self._build()
        self.set_state(self.x)

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
    """``hsddp_gym/BoundingMuJoCo-v0``: [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (same observation, action,
    reward, reset, termination, info and arguments) simulated by MuJoCo ([`MuJoCoSimulator`][MuJoCoSimulator]) instead
    of the exact-LCP contact simulator. Contact flags are set when MuJoCo reports a positive normal force on the foot in
    the last MuJoCo step. ``contact_erp`` and ``energy_consistent`` do not apply (accepted, ignored).

    Extra (keyword) arguments, the contact model (``ValueError`` naming the argument for a value out of range):

    | argument | default | meaning |
    |---|---|---|
    | ``contact_model`` | None | a [`ContactModel`][ContactModel], a dict of its fields or a corner name (None: the
    default) |
    | ``cone`` | ``"elliptic"`` | friction cone, ``"elliptic"`` or ``"pyramidal"`` |
    | ``solref`` | (0.005, 1) | (time constant in [0.5, 100] ms, damping ratio in [0.1, 10]) |
    | ``solimp`` | (0.9, 0.95, 0.001, 0.5, 2) | MuJoCo's impedance shape (see [`ContactModel`][ContactModel]) |
    | ``foot_radius`` | 0.005 | foot sphere radius [m], in [0.5, 50] mm |
    | ``impratio`` | 1 | frictional / normal impedance ratio, in [1, 100] |
    | ``sim_timestep`` | 0.001 | MuJoCo step [s]: 5 ms / n, n = 1..20 |
    | ``friction`` | 0.6 | Coulomb ``mu``, in [0.01, 2] |
    | ``frame_skip`` | None | steps per action (None: 5 ms / ``sim_timestep``, the control period stays 5 ms) |

    Each of ``cone`` .. ``friction`` given (not None) replaces that field of ``contact_model``; the model
    simulated is `contact_model`. [`set_contact_model`][set_contact_model] changes it between episodes
    ([`RandomContactModel`][hsddp_gym.envs.perturbations.wrappers.RandomContactModel] draws one per episode).
    """

    def __init__(self, *, contact_model=None, cone: str | None = None, solref=None, solimp=None,
                 foot_radius: float | None = None, impratio: float | None = None, sim_timestep: float | None = None,
                 friction: float | None = None, frame_skip: int | None = None, **kwargs) -> None:
        self.contact_model = _resolve(contact_model, None, cone=cone, solref=solref, solimp=solimp,
                                      foot_radius=foot_radius, impratio=impratio, timestep=sim_timestep,
                                      friction=friction)
        self._frame_skip_argument = frame_skip
        super().__init__(frame_skip=self.contact_model.frame_skip if frame_skip is None else frame_skip,
                         sim_timestep=self.contact_model.timestep, friction=self.contact_model.friction, **kwargs)

    def _make_simulator(self, friction, gravity, contact_erp, motor_speed_limits, energy_consistent):
        self._sim_arguments = (gravity, motor_speed_limits)
        return MuJoCoSimulator(self.robot, gravity=gravity, motor_speed_limits=motor_speed_limits,
                               torque_limit=self.torque_limit, contact_model=self.contact_model, terrain=self.terrain)

    def set_contact_model(self, contact_model) -> None:
        """Simulate ``contact_model`` (a [`ContactModel`][ContactModel], a dict of its fields or a corner name) from the
        next `reset` on: the MuJoCo model is rebuilt, ``sim_timestep`` becomes the model's and, unless
        ``frame_skip`` was given, ``frame_skip`` becomes ``5 ms / sim_timestep`` (the control period stays 5 ms).
        Call `reset` before stepping again."""
        model = ContactModel.parse(contact_model, "contact_model")
        if model == self.contact_model:
            return
        self.contact_model = model
        self.sim_timestep = model.timestep
        if self._frame_skip_argument is None:
            self.frame_skip = model.frame_skip
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / self.dt))}
        gravity, motor_speed_limits = self._sim_arguments
        self.sim = self._make_simulator(model.friction, gravity, None, motor_speed_limits, None)
        self.sim.set_state(self.init_state)
        self._update_feet(at_reset=True)

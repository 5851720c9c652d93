"""The numbers behind the physics table of the env's docs: the energy-consistent scheme (the default), the legacy
one (``energy_consistent=False``) and the MuJoCo twin, with the states of ``tests/test_env_physics.py``.

Prints, per scheme:

* the largest ``E(t+h) - E(t) - tau . dq`` over single 1 ms steps from random states in every contact
  combination (zero torque with g = 9.81 and 0; random torques);
* free flight (g = 0, zero torque, the trunk moving and pitching, the joints spinning at up to 10, 50, 100, 300
  rad/s) over ``--flight-seconds`` (10 s): the relative drift of the energy, of the linear momentum and of the
  angular momentum about the centre of mass (all three must stay constant);
* the largest per-step motion of a sticking foot in a rocking double stance, the deepest foot after landings at
  1, 5, 10 m/s;
* tunnelling: the deepest foot at the end of any 1 ms step from ``--bound-states`` start states at the reset
  velocity bounds (joints up to 98 rad/s, lowest foot 1 mm up), 1 s each of zero torque or of bang-bang torque
  (the torque limit, its sign flipped every 5 ms control step), with the motor speed limits and with ideal
  torques;
* the throughput of ``Bounding-v0`` (default frame skip, random actions) as a ratio to HalfCheetah-v5 timed
  interleaved in the same run (when ``gymnasium[mujoco]`` is installed).

Usage::

    python experiments/env_physics.py [--states 20] [--steps 120] [--flight-seconds 10] [--bound-states 40]
                                      [--seconds 2] [--record results/env/physics.json]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

from hsddp_gym.core.model import CheetahModel
from hsddp_gym.envs.bounding import DEFAULT_MOTOR_SPEED_LIMITS
from hsddp_gym.envs.contact import ContactSimulator
from hsddp_gym.reports.store import machine_info, write_record

FLIGHT_RATES = (10.0, 50.0, 100.0, 300.0)
LANDING_SPEEDS = (1.0, 5.0, 10.0)
TORQUE_LIMIT = 33.0
SCHEMES = ("energy_consistent", "legacy", "mujoco")
SCHEME_NAMES = {"energy_consistent": "energy-consistent (default)", "legacy": "legacy (energy_consistent=False)",
                "mujoco": "MuJoCo twin (BoundingMuJoCo-v0's simulator)"}


def finite_or_none(value: float) -> float | None:
    """``value``, or ``None`` when it is not finite (a blow-up; JSON has no NaN)."""
    return float(value) if math.isfinite(value) else None


def make_sim(scheme: str, robot: CheetahModel, **kwargs):
    """The simulator of ``scheme`` (see :data:`SCHEMES`) with ContactSimulator's keyword arguments."""
    if scheme == "mujoco":
        from hsddp_gym.envs.mujoco_twin import MuJoCoSimulator

        if kwargs.get("motor_speed_limits") is not None:
            kwargs["torque_limit"] = TORQUE_LIMIT
        return MuJoCoSimulator(robot, **kwargs)
    return ContactSimulator(robot, energy_consistent=scheme == "energy_consistent", **kwargs)


def centroidal_momentum(robot: CheetahModel, data, x: np.ndarray) -> np.ndarray:
    """Linear x, z and angular y momentum about the centre of mass (3,) of the state ``x`` (14,)."""
    return pin.computeCentroidalMomentum(robot.model, data, x[:7], x[7:]).np[[0, 2, 4]].copy()


def flight_state(rate: float) -> np.ndarray:
    """2 m up, moving forward and up, pitching, the joints spinning at up to ``rate`` rad/s (14,)."""
    x = np.zeros(14)
    x[1] = 2.0
    x[3:7] = 0.7, -1.4, 0.7, -1.4
    x[7], x[8], x[9] = 1.0, 0.3, 2.0
    x[10:14] = rate, -0.5 * rate, 0.3 * rate, -0.8 * rate
    return x


def free_flight_drift(scheme: str, robot: CheetahModel, rate: float, seconds: float) -> dict:
    """Relative drifts of the energy and of the linear and angular momentum over ``seconds`` of free flight."""
    sim = make_sim(scheme, robot, gravity=0.0)
    x = flight_state(rate)
    sim.set_state(x)
    data = robot.model.createData()
    e0, p0 = sim.energy(), centroidal_momentum(robot, data, x)
    with np.errstate(all="ignore"):
        sim.run(np.zeros(4), int(round(seconds / sim.dt)))
        p = centroidal_momentum(robot, data, sim.x.copy())
        drift = {"energy": abs(sim.energy() / e0 - 1.0),
                 "linear_momentum": float(np.linalg.norm(p[:2] - p0[:2]) / np.linalg.norm(p0[:2])),
                 "angular_momentum": float(abs(p[2] - p0[2]) / abs(p0[2]))}
    if not np.all(np.isfinite(sim.x)) or bool(sim.contact.any()):
        drift = {k: math.inf for k in drift}  # blew up (or fell back to the ground): no meaningful drift
    return {k: finite_or_none(v) for k, v in drift.items()}


def bound_states(robot: CheetahModel, n: int, seed: int = 43) -> list[np.ndarray]:
    """``n`` start states at the reset velocity bounds (see :func:`test_env_physics.bound_state`)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_env_physics import bound_state

    rng = np.random.default_rng(seed)
    return [bound_state(robot, rng) for _ in range(n)]


def tunnelling_depth(scheme: str, robot: CheetahModel, states: list, actions: str, motor_limits: bool) -> float:
    """The deepest foot [mm] at the end of any 1 ms step over 1 s from each state (see the module docstring)."""
    deepest = 0.0
    for x in states:
        sim = make_sim(scheme, robot, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS if motor_limits else None)
        sim.set_state(x)
        with np.errstate(all="ignore"):
            for t in range(1000):
                sign = 0.0 if actions == "zero" else (1.0 if (t // 5) % 2 == 0 else -1.0)
                sim.run(np.full(4, sign * TORQUE_LIMIT), 1)
                if not np.all(np.isfinite(sim.x)):
                    return math.inf
                deepest = max(deepest, -float(sim.foot_heights().min()))
    return 1e3 * deepest


def throughput_ratio(seconds: float, seed: int = 0) -> dict | None:
    """Bounding-v0 and HalfCheetah-v5 env steps/s under random actions, timed in interleaved chunks."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_env import time_env

    try:
        cheetah = gym.make("HalfCheetah-v5")
    except Exception as exc:  # gymnasium[mujoco] missing: report it, do not fail the physics checks
        print(f"  (HalfCheetah-v5 unavailable: {exc}; no throughput ratio)")
        return None
    ours = gym.make("hsddp_gym/Bounding-v0")
    rates = {"bounding": [], "halfcheetah": []}
    chunks = 4
    for k in range(chunks):
        rates["bounding"].append(time_env(ours, seconds / chunks, seed + k, "random")[0])
        rates["halfcheetah"].append(time_env(cheetah, seconds / chunks, seed + k, "random")[0])
    bounding, halfcheetah = float(np.median(rates["bounding"])), float(np.median(rates["halfcheetah"]))
    return {"bounding_env_steps_per_s": bounding, "halfcheetah_env_steps_per_s": halfcheetah,
            "ratio": bounding / halfcheetah}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--states", type=int, default=20, help="random states per contact combination (default: 20)")
    p.add_argument("--steps", type=int, default=120, help="1 ms steps from each state (default: 120)")
    p.add_argument("--flight-seconds", type=float, default=10.0,
                   help="simulated seconds of each free flight (default: 10)")
    p.add_argument("--bound-states", type=int, default=40,
                   help="start states at the reset velocity bounds for the tunnelling check (default: 40)")
    p.add_argument("--seconds", type=float, default=2.0,
                   help="wall-clock seconds of the throughput timing, per env (default: 2; 0 skips it)")
    p.add_argument("--record", default=None, metavar="FILE.json",
                   help="also write the measurements as a record of the results store (results/env/physics.json)")
    args = p.parse_args(argv)
    if args.states < 1 or args.steps < 1 or args.bound_states < 1:
        p.error("--states, --steps and --bound-states must be >= 1")
    if not args.flight_seconds > 0.0 or not args.seconds >= 0.0:
        p.error("--flight-seconds must be > 0 and --seconds >= 0")
    machine = machine_info()
    record = {"states_per_combination": args.states, "steps": args.steps, "flight_seconds": args.flight_seconds,
              "bound_states": args.bound_states, "schemes": {}}
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_env_physics import COMBOS, energy_excess, random_state, stick_drift

    robot = CheetahModel()
    starts = bound_states(robot, args.bound_states)
    try:
        from hsddp_gym.envs.mujoco_twin import _import_mujoco

        _import_mujoco()
        schemes = SCHEMES
    except ImportError:
        print("(mujoco is not installed: the MuJoCo twin's column is left out)")
        schemes = SCHEMES[:2]
    for scheme in schemes:
        print(f"== {SCHEME_NAMES[scheme]}")
        rec = record["schemes"][scheme] = {"free_flight_drift": {}, "landing_depth_mm": {}, "tunnelling_mm": {}}
        if scheme != "mujoco":  # the per-step energy balance and the stick are checks of this scheme's LCP
            rec["energy_excess_J"] = {}
            for gravity, torques in ((9.81, False), (0.0, False), (9.81, True)):
                sim = make_sim(scheme, robot, gravity=gravity, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS)
                rng = np.random.default_rng(0)
                worst = -np.inf
                with np.errstate(all="ignore"):
                    for combo in COMBOS:
                        for _ in range(args.states):
                            u = rng.uniform(-33.0, 33.0, 4) if torques else None
                            worst = max(worst, energy_excess(sim, random_state(robot, rng, combo, 1.0), args.steps, u))
                label = f"g={gravity:g}, {'random torques' if torques else 'zero torque'}"
                rec["energy_excess_J"][label] = worst
                print(f"  max per-step dE - tau.dq, {label}, {4 * args.states} states x {args.steps} steps: "
                      f"{worst:+.3e} J")
            drift, _ = stick_drift(robot, scheme == "energy_consistent")
            rec["stick_drift_m"] = drift
            print(f"  sticking foot, largest motion in one step (200 ms rocking double stance): {drift:.3e} m")
        for rate in FLIGHT_RATES:
            d = rec["free_flight_drift"][f"{rate:g}"] = free_flight_drift(scheme, robot, rate, args.flight_seconds)
            shown = ", ".join(f"{k} {'blow-up' if v is None else f'{v:.1e}'}" for k, v in d.items())
            print(f"  free flight {args.flight_seconds:g} s, g = 0, joints up to {rate:g} rad/s, relative drift: "
                  f"{shown}")
        depths = []
        for speed in LANDING_SPEEDS:
            deepest = np.inf
            for pitch in (0.0, 0.2):
                sim = make_sim(scheme, robot, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS)
                q = np.array([0.0, 0.0, pitch, 0.25 * np.pi, -0.5 * np.pi, 0.25 * np.pi, -0.5 * np.pi])
                q[1] = -robot.foot_heights(q).min() + 0.02
                xl = np.r_[q, np.zeros(7)]
                xl[7], xl[8] = 0.5, -speed
                sim.set_state(xl)
                for _ in range(300):
                    sim.run(np.zeros(4), 1)
                    deepest = min(deepest, float(sim.foot_heights().min()))
            depths.append(f"{speed:g} m/s: {1e3 * max(0.0, -deepest):.3f} mm")
            rec["landing_depth_mm"][f"{speed:g}"] = 1e3 * max(0.0, -deepest)
        print("  deepest foot after a landing (zero torque, pitch 0 and 0.2): " + ", ".join(depths))
        for motor_limits in (True, False):
            for actions in ("zero", "bang_bang"):
                key = f"{actions}, {'motor limits' if motor_limits else 'ideal torques'}"
                depth = tunnelling_depth(scheme, robot, starts, actions, motor_limits)
                rec["tunnelling_mm"][key] = finite_or_none(depth)
                print(f"  deepest foot from {len(starts)} bound states, {key}: "
                      f"{'blow-up' if not math.isfinite(depth) else f'{depth:.3g} mm'}")
    if args.seconds > 0.0:
        print("== throughput (default frame skip, random actions, interleaved)")
        record["throughput"] = throughput_ratio(args.seconds)
        if record["throughput"]:
            t = record["throughput"]
            print(f"  Bounding-v0 {t['bounding_env_steps_per_s']:,.0f} env steps/s, HalfCheetah-v5 "
                  f"{t['halfcheetah_env_steps_per_s']:,.0f}: ratio {t['ratio']:.2f}")
    if args.record:
        write_record(args.record, record, "Physical checks of Bounding-v0's contact scheme (energy per step, free-"
                     "flight invariants, sticking, landing depth, tunnelling from bound states, throughput), the "
                     "energy-consistent scheme beside the legacy one and the MuJoCo twin", machine=machine)
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The numbers behind the README's physics table, for the energy-consistent scheme and the legacy one
(``energy_consistent=False``), with the same states as ``tests/test_env_physics.py``.

Prints, per scheme: the largest ``E(t+h) - E(t) - tau . dq`` over single 1 ms steps from random states in
every contact combination (zero torque, g = 9.81 and 0; random torques), the spinning-leg energy ratio
``E(0.5 s) / E(0)`` in free flight (g = 0) at 10, 50, 75, 100 rad/s, the largest per-step motion of a sticking
foot in a rocking double stance, and the deepest foot after landings at 1, 5, 10 m/s.

Usage::

    python experiments/env_physics.py [--states 20] [--steps 120] [--record results/env/physics.json]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hsddp_gym.core.model import CheetahModel
from hsddp_gym.envs.bounding import DEFAULT_MOTOR_SPEED_LIMITS
from hsddp_gym.envs.contact import ContactSimulator
from hsddp_gym.reports.store import machine_info, write_record


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--states", type=int, default=20, help="random states per contact combination (default: 20)")
    p.add_argument("--steps", type=int, default=120, help="1 ms steps from each state (default: 120)")
    p.add_argument("--record", default=None, metavar="FILE.json",
                   help="also write the measurements as a record of the results store (results/env/physics.json)")
    args = p.parse_args(argv)
    if args.states < 1 or args.steps < 1:
        p.error("--states and --steps must be >= 1")
    machine = machine_info()
    record = {"states_per_combination": args.states, "steps": args.steps, "schemes": {}}
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_env_physics import COMBOS, energy_excess, random_state, stick_drift

    robot = CheetahModel()
    for consistent in (True, False):
        name = "energy-consistent (default)" if consistent else "legacy (energy_consistent=False)"
        print(f"== {name}")
        rec = record["schemes"]["energy_consistent" if consistent else "legacy"] = {
            "energy_excess_J": {}, "free_flight_energy_ratio": {}, "landing_depth_mm": {}}
        for gravity, torques in ((9.81, False), (0.0, False), (9.81, True)):
            sim = ContactSimulator(robot, gravity=gravity, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS,
                                   energy_consistent=consistent)
            rng = np.random.default_rng(0)
            worst = -np.inf
            with np.errstate(all="ignore"):
                for combo in COMBOS:
                    for _ in range(args.states):
                        u = rng.uniform(-33.0, 33.0, 4) if torques else None
                        worst = max(worst, energy_excess(sim, random_state(robot, rng, combo, 1.0), args.steps, u))
            rec["energy_excess_J"][f"g={gravity:g}, {'random torques' if torques else 'zero torque'}"] = worst
            print(f"  max per-step dE - tau.dq, g = {gravity:g}, {'random torques' if torques else 'zero torque'}, "
                  f"{4 * args.states} states x {args.steps} steps: {worst:+.3e} J")
        ratios = []
        for rate in (10.0, 50.0, 75.0, 100.0):
            x = np.zeros(14)
            x[1] = 2.0
            x[3], x[4], x[5], x[6] = 0.7, -1.4, 0.7, -1.4
            x[7], x[10] = 1.0, rate
            sim = ContactSimulator(robot, gravity=0.0, energy_consistent=consistent)
            sim.set_state(x)
            e0 = sim.energy()
            with np.errstate(all="ignore"):
                sim.run(np.zeros(4), 500)
                ratios.append(f"{rate:g} rad/s: {sim.energy() / e0:.4g}")
                rec["free_flight_energy_ratio"][f"{rate:g}"] = sim.energy() / e0
        print("  spinning front hip, free flight, g = 0, E(0.5 s)/E(0): " + ", ".join(ratios))
        drift, _ = stick_drift(robot, consistent)
        rec["stick_drift_m"] = drift
        print(f"  sticking foot, largest motion in one step (200 ms rocking double stance): {drift:.3e} m")
        depths = []
        for speed in (1.0, 5.0, 10.0):
            deepest = np.inf
            for pitch in (0.0, 0.2):
                sim = ContactSimulator(robot, motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS,
                                       energy_consistent=consistent)
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
    if args.record:
        write_record(args.record, record, "Physical checks of Bounding-v0's contact scheme (energy per step, "
                     "free-flight energy, sticking, landing depth), the energy-consistent and the legacy scheme",
                     machine=machine)
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

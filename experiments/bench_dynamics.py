"""Benchmark the hybrid dynamics: microseconds per call of every public and hot-path entry point.

Measures, per contact mode, ``HybridDynamics.step`` (public, checked), ``simulate_step`` (the rollout hot
path), ``step_derivatives`` (public) and ``linearize`` (the solver hot path, per knot of a constant-mode
horizon); ``linearize`` and the open-loop rollout per knot of the paper's 1480-knot bounding trajectory
(5 cycles of 80/72/72/72 ms, heuristic controller, from the paper's initial state); ``reset_map`` and
``reset_map_jacobian`` per post-impact mode; and Pinocchio's raw calls as the reference (``linearize`` and the
solver's rollouts run the compiled dynamics of :mod:`hsddp_gym.core.planar_dynamics`, the single-step methods
Pinocchio's). Every figure is the best of ``--repeat`` timeit repeats (default 5), each long enough to last
``--min-time`` seconds.

The target for the solver is step + all derivatives <= 30 us per knot; the script prints two measures per
knot of the bounding trajectory and their ratios to the target: the solver's fused path (one rollout that
linearizes every knot on the way, what a DDP iteration pays) and a separate rollout followed by a separate
``linearize`` pass.

Usage::

    python experiments/bench_dynamics.py [--repeat 5] [--min-time 0.05] [--integrator euler]
"""

from __future__ import annotations

import argparse
import platform
import timeit

import numpy as np
import pinocchio as pin

from hsddp_gym.core.conventions import NGRF, NQ, NX, Mode
from hsddp_gym.core.dynamics import INTEGRATORS, HybridDynamics, Linearization
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.core.rollout import Trajectory, rollout
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController
from hsddp_gym.reports.store import machine_info, write_record

TARGET_US_PER_KNOT = 30.0
MODES = (Mode.FLIGHT, Mode.FRONT_STANCE, Mode.BACK_STANCE, Mode.DOUBLE_STANCE)


def best_us(fn, repeat: int, min_time: float, per: int = 1) -> float:
    """Best-of-``repeat`` time of ``fn()`` in microseconds, divided by ``per`` (e.g. knots per call)."""
    timer = timeit.Timer(fn)
    number = 1
    while True:  # like Timer.autorange, with a shorter target so the whole table takes seconds
        if timer.timeit(number) >= min_time:
            break
        number *= 2 if number < 8 else 4
    return 1e6 * min(timer.repeat(repeat=repeat, number=number)) / number / per


def bounding_trajectory(dyn: HybridDynamics, cycles: int) -> Trajectory:
    schedule = ModeSchedule.bounding(cycles)
    controller = HeuristicBoundingController(dyn.robot).as_schedule_controller(schedule)
    return rollout(dyn, schedule, paper_initial_state(), controller=controller)


def mode_states(traj: Trajectory) -> dict[Mode, tuple[np.ndarray, np.ndarray]]:
    """A representative (x, u) per mode: mid-phase knots of the bounding trajectory (the paper's initial
    state with its first control for double stance, which bounding never uses)."""
    out = {}
    for mode in MODES:
        knots = np.flatnonzero(traj.modes == int(mode))
        k = int(knots[len(knots) // 2]) if knots.size else 0
        out[mode] = (traj.X[k].copy(), traj.U[k].copy())
    return out


def touchdown_states(traj: Trajectory) -> dict[Mode, np.ndarray]:
    """A pre-impact state per post-impact mode (the end of a flight phase where possible)."""
    schedule = traj.schedule
    out = {}
    for i in range(len(schedule) - 1):
        out.setdefault(schedule.next_mode(i), traj.X_pre[i].copy())
    x = traj.X_pre[1].copy()  # just before the front touchdown: both feet near the ground
    out.setdefault(Mode.DOUBLE_STANCE, x)
    out.setdefault(Mode.FLIGHT, traj.X_pre[0].copy())
    return out


def bench_modes(dyn: HybridDynamics, traj: Trajectory, args) -> dict[str, dict[Mode, float]]:
    rows: dict[str, dict[Mode, float]] = {}
    states = mode_states(traj)
    x_next, grf = np.empty(NX), np.empty(NGRF)
    n = traj.U.shape[0]
    lin = Linearization(n)
    for mode in MODES:
        x, u = states[mode]
        m = int(mode)
        rows.setdefault("step (public, checked)", {})[mode] = best_us(
            lambda x=x, u=u, mode=mode: dyn.step(x, u, mode), args.repeat, args.min_time)
        rows.setdefault("simulate_step (hot path)", {})[mode] = best_us(
            lambda x=x, u=u, m=m: dyn.simulate_step(x, u, m, x_next, grf), args.repeat, args.min_time)
        rows.setdefault("step_derivatives (public)", {})[mode] = best_us(
            lambda x=x, u=u, mode=mode: dyn.step_derivatives(x, u, mode), args.repeat, args.min_time)
        const_modes = np.full(n, m, dtype=np.int64)
        rows.setdefault(f"linearize, {n} knots all in this mode (per knot)", {})[mode] = best_us(
            lambda const_modes=const_modes: dyn.linearize(traj.X, traj.U, const_modes, lin),
            args.repeat, args.min_time, per=n)
    pre = touchdown_states(traj)
    for mode in MODES:
        x = pre[mode]
        rows.setdefault("reset_map into mode (FL = lift-off)", {})[mode] = best_us(
            lambda x=x, mode=mode: dyn.reset_map(x, mode), args.repeat, args.min_time)
        rows.setdefault("reset_map_jacobian into mode", {})[mode] = best_us(
            lambda x=x, mode=mode: dyn.reset_map_jacobian(x, mode), args.repeat, args.min_time)
    return rows


def bench_trajectory(dyn: HybridDynamics, traj: Trajectory, args) -> dict[str, float]:
    n = traj.U.shape[0]
    lin = Linearization(n)
    schedule = traj.schedule
    x0 = traj.X[0]
    return {
        "linearize (solver hot path)": best_us(lambda: dyn.linearize(traj.X, traj.U, traj.modes, lin),
                                               args.repeat, args.min_time, per=n),
        "rollout, open-loop controls (simulate_step + resets)": best_us(
            lambda: rollout(dyn, schedule, x0, controls=traj.U), args.repeat, args.min_time, per=n),
    }


def bench_fused(dyn: HybridDynamics, traj: Trajectory, args) -> float:
    """µs per knot of the solver's own step + all derivatives: one policy rollout that linearizes every knot
    on the way (``hsddp_gym.planners.optimizer.hsddp.rollout_policy`` with ``lin``, the full-step line-search trial),
    here with the open-loop controls of ``traj`` (no feedback), including the resets."""
    from hsddp_gym.planners.optimizer.hsddp import _Traj, rollout_policy
    from hsddp_gym.planners.optimizer.problem import HybridProblem

    n = traj.U.shape[0]
    problem = HybridProblem.bounding(args.cycles, dynamics=dyn)
    if problem.n_knots != n:
        raise RuntimeError(f"problem has {problem.n_knots} knots, trajectory {n}")
    out, lin = _Traj(n, problem.n_phases), Linearization(n)
    return best_us(lambda: rollout_policy(problem, out, traj.U, lin=lin), args.repeat, args.min_time, per=n)


def bench_pinocchio_floor(dyn: HybridDynamics, traj: Trajectory, args) -> list[tuple[str, float]]:
    """Pinocchio's own calls on fresh Data objects (no Python glue beyond the call)."""
    model = dyn.model
    robot = dyn.robot
    prox = pin.ProximalSettings(1e-12, 1e-8, 20)
    states = mode_states(traj)
    out = []
    for mode in (Mode.BACK_STANCE, Mode.DOUBLE_STANCE):
        x, u = states[mode]
        q, v = x[:NQ], x[NQ:]
        tau = np.concatenate([np.zeros(3), u])
        cms, cds = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
        for foot in mode.feet:
            frame = model.frames[robot.foot_frame_ids[foot]]
            cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, frame.parentJoint, frame.placement,
                                          pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            cms.append(cm)
            cds.append(cm.createData())
        data = model.createData()
        pin.initConstraintDynamics(model, data, cms, cds)
        label = "1 foot" if len(mode.feet) == 1 else "2 feet"
        t_cd = best_us(lambda q=q, v=v, tau=tau, data=data, cms=cms, cds=cds:
                       pin.constraintDynamics(model, data, q, v, tau, cms, cds, prox), args.repeat, args.min_time)
        t_both = best_us(lambda q=q, v=v, tau=tau, data=data, cms=cms, cds=cds: (
            pin.constraintDynamics(model, data, q, v, tau, cms, cds, prox),
            pin.computeConstraintDynamicsDerivatives(model, data, cms, cds, prox)), args.repeat, args.min_time)
        out.append((f"constraintDynamics, {label}", t_cd))
        out.append((f"constraintDynamics + computeConstraintDynamicsDerivatives, {label}", t_both))
    x, u = states[Mode.FLIGHT]
    q, v = x[:NQ], x[NQ:]
    tau = np.concatenate([np.zeros(3), u])
    data = model.createData()
    out.append(("aba (flight)", best_us(lambda: pin.aba(model, data, q, v, tau), args.repeat, args.min_time)))
    out.append(("computeABADerivatives (flight)",
                best_us(lambda: pin.computeABADerivatives(model, data, q, v, tau), args.repeat, args.min_time)))
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=5, help="timeit repeats; the best is kept (default 5)")
    parser.add_argument("--min-time", type=float, default=0.05,
                        help="minimum seconds per repeat; sets the number of calls per repeat (default 0.05)")
    parser.add_argument("--integrator", choices=INTEGRATORS, default="euler", help="default: euler (paper)")
    parser.add_argument("--cycles", type=int, default=5, help="bounding cycles of the trajectory (default 5)")
    parser.add_argument("--record", default=None, metavar="FILE.json",
                        help="also write the measurements as a record of the results store "
                             "(results/speed/dynamics.json)")
    args = parser.parse_args(argv)
    machine = machine_info()
    if args.repeat < 1 or args.min_time <= 0 or args.cycles < 1:
        parser.error("--repeat and --cycles must be >= 1 and --min-time > 0")

    dyn = HybridDynamics(integrator=args.integrator)
    traj = bounding_trajectory(dyn, args.cycles)
    n = traj.U.shape[0]
    counts = {m: int(np.sum(traj.modes == int(m))) for m in MODES}
    print(f"hsddp_gym dynamics benchmark -- Pinocchio {pin.__version__}, numpy {np.__version__}, "
          f"Python {platform.python_version()}, integrator={args.integrator}, dt={dyn.dt:g} s")
    print(f"best of {args.repeat} timeit repeats (>= {args.min_time:g} s each); all times in microseconds\n")

    rows = bench_modes(dyn, traj, args)
    width = max(len(k) for k in rows) + 2
    print(f"{'per call, by contact mode':<{width}}" + "".join(f"{m.short:>9}" for m in MODES))
    print("-" * (width + 9 * len(MODES)))
    for name, by_mode in rows.items():
        print(f"{name:<{width}}" + "".join(f"{by_mode[m]:9.2f}" for m in MODES))

    print(f"\nbounding trajectory: {args.cycles} cycles, {n} knots "
          f"(FL {counts[Mode.FLIGHT]}, FS {counts[Mode.FRONT_STANCE]}, BS {counts[Mode.BACK_STANCE]}), "
          f"{len(traj.schedule) - 1} resets")
    traj_rows = bench_trajectory(dyn, traj, args)
    width2 = max(len(k) for k in traj_rows) + 2
    for name, us in traj_rows.items():
        print(f"  {name:<{width2}}{us:9.2f} us/knot   ({us * n / 1e3:7.2f} ms per trajectory)")
    measured = sum(traj_rows.values())
    sim = rows["simulate_step (hot path)"]
    dynamics_only = sum(counts[m] * sim[m] for m in MODES) / n + traj_rows["linearize (solver hot path)"]
    print(f"  {'step + all derivatives = rollout + linearize':<{width2}}{measured:9.2f} us/knot")
    print(f"  {'  (simulate_step alone, mode-weighted, + linearize)':<{width2}}{dynamics_only:9.2f} us/knot")
    fused = bench_fused(dyn, traj, args)
    print(f"  {'fused: rollout that linearizes on the way (solver path)':<{width2}}{fused:9.2f} us/knot")
    print(f"\ntarget: step + all derivatives <= {TARGET_US_PER_KNOT:.0f} us/knot")
    for label, value in (("as the solver computes them (fused)", fused), ("separate rollout + linearize", measured)):
        print(f"  {label:<38}{value:7.2f} us/knot, ratio measured/target = {value / TARGET_US_PER_KNOT:.2f} "
              f"({'meets' if value <= TARGET_US_PER_KNOT else 'MISSES'} the target)")

    print("\nreference: Pinocchio's raw calls (fresh Data, no wrapper)")
    floor = bench_pinocchio_floor(dyn, traj, args)
    width3 = max(len(k) for k, _ in floor) + 2
    for name, us in floor:
        print(f"  {name:<{width3}}{us:9.2f}")
    lin_floor = {m: dict(floor)[f"constraintDynamics + computeConstraintDynamicsDerivatives, {lab}"]
                 for m, lab in ((Mode.BACK_STANCE, "1 foot"), (Mode.DOUBLE_STANCE, "2 feet"))}
    lin_floor[Mode.FRONT_STANCE] = lin_floor[Mode.BACK_STANCE]
    lin_floor[Mode.FLIGHT] = dict(floor)["computeABADerivatives (flight)"]
    key = f"linearize, {n} knots all in this mode (per knot)"
    print("  linearize (compiled) / Pinocchio's derivative calls, per knot: "
          + ", ".join(f"{m.short} {rows[key][m] / lin_floor[m]:.2f}" for m in MODES))
    if args.record:
        data = {"integrator": args.integrator, "cycles": args.cycles, "knots": n,
                "per_call_us": {name: {m.short: by_mode[m] for m in MODES} for name, by_mode in rows.items()},
                "per_knot_us": dict(traj_rows), "fused_per_knot_us": fused, "target_per_knot_us": TARGET_US_PER_KNOT,
                "pinocchio_us": dict(floor), "linearize_key": key,
                "pinocchio_derivatives_per_knot_us": {m.short: lin_floor[m] for m in MODES}}
        write_record(args.record, data, "Microseconds per call of the hybrid dynamics and their derivatives, by "
                     "contact mode, beside Pinocchio's own calls measured in the same run", machine=machine)
        print(f"wrote {args.record}")


if __name__ == "__main__":
    main()

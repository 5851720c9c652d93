"""The table of the env's physical claims (energy, momentum, contact) for each contact scheme."""

from __future__ import annotations

from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.markdown import markdown_table, source_line


def env_physics(store: Store) -> str:
    """The env's physical claims: the energy-consistent scheme (default) beside the legacy one and the MuJoCo twin."""
    d = store.data("env/physics")
    names = [k for k in ("energy_consistent", "legacy", "mujoco") if k in d["schemes"]]
    schemes = [d["schemes"][k] for k in names]
    n = 4 * d["states_per_combination"]

    def cells(fn):
        return [fn(rec) for rec in schemes]

    def energy(key):
        return cells(lambda rec: f"{rec['energy_excess_J'][key]:+.1e} J" if "energy_excess_J" in rec else "–")

    def joined(values, fmt):
        return " / ".join("blow-up" if v is None else format(v, fmt) for v in values)

    e = schemes[0]
    rates = " / ".join(e["free_flight_drift"])
    speeds = " / ".join(e["landing_depth_mm"])
    seconds = f"{d['flight_seconds']:g} s"
    rows = [
        [f"largest ΔE per 1 ms step, zero torque, g = 9.81 ({n} states in all contact combinations × "
         f"{d['steps']} steps)", *energy("g=9.81, zero torque")],
        ["the same, g = 0", *energy("g=0, zero torque")],
        ["largest ΔE − τ·Δq per step, random constant torques", *energy("g=9.81, random torques")],
    ]
    for key, what in (("energy", "energy"), ("linear_momentum", "linear momentum"),
                      ("angular_momentum", "angular momentum about the CoM")):
        rows.append([f"free flight, g = 0, zero torque, joints up to {rates} rad/s: relative drift of the {what} "
                     f"over {seconds}",
                     *cells(lambda rec, key=key: joined([v[key] for v in rec["free_flight_drift"].values()], ".1e"))])
    rows.append(["sticking foot, largest motion in one step (rocking double stance)",
                 *cells(lambda rec: f"{rec['stick_drift_m']:.1e} m" if "stick_drift_m" in rec else "–")])
    rows.append([f"deepest foot after landings at {speeds} m/s [mm]",
                 *cells(lambda rec: joined(rec["landing_depth_mm"].values(), ".3g"))])
    for key in e["tunnelling_mm"]:
        rows.append([f"deepest foot at the end of any 1 ms step, {d['bound_states']} start states at the reset "
                     f"bounds, 1 s of {key.replace('bang_bang', 'bang-bang torque').replace('zero,', 'zero torque,')}"
                     " [mm]", *cells(lambda rec, key=key: joined([rec["tunnelling_mm"][key]], ".3g"))])
    header = ["claim", "default scheme", "legacy scheme (`energy_consistent=False`)",
              "MuJoCo twin (soft contacts)"][:1 + len(names)]
    lines = [markdown_table(header, rows), ""]
    t = d.get("throughput")
    if t:
        lines += [f"Throughput (default frame skip, random actions, timed interleaved in the same run): Bounding-v0 "
                  f"{t['bounding_env_steps_per_s']:,.0f} env steps/s, HalfCheetah-v5 "
                  f"{t['halfcheetah_env_steps_per_s']:,.0f}: **{t['ratio']:.2f}×** HalfCheetah-v5.", ""]
    lines.append(source_line(store, "env/physics"))
    return "\n".join(lines)

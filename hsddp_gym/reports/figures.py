"""Every results figure of the README and the documentation site, drawn from the records of the results store.

Each figure is a function of record data; [`FIGURES`][FIGURES] maps a published figure (its path under the repository)
to the record it is drawn from and the function that draws it. The experiment scripts call the same functions on
the data they record, so a figure from a run and a figure from the store are the same drawing.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.viz import plotting

FIG5_SNAPSHOTS = 14
"""Snapshots per motion in Fig. 5 (the record keeps exactly these states)."""


def paper_task1(data: dict, out_dir) -> list[Path]:
    """Paper Figs. 4, 5 and 6 from a task-1 record's data (``experiments/paper_task1.py``).

    Returns:
        the written paths: ``fig4_convergence.png``, ``fig5_motion.png``, ``fig6_forces_torques.png``.
    """
    from hsddp_gym.core.model import CheetahModel

    out_dir = Path(out_dir)
    fig = data["figures"]
    fig5 = fig["fig5"]
    snapshots = {label: np.asarray(v["snapshots"], dtype=float) for label, v in fig5.items()}
    touchdowns = {label: [tuple(p) for p in v["touchdowns"]] for label, v in fig5.items()}
    paths = [plotting.plot_convergence(fig["fig4"], out_dir / "fig4_convergence.png")]
    # The snapshots are the motion's states at FIG5_SNAPSHOTS evenly spaced knots: drawn as a motion of that many
    # knots, with the knot spacing that keeps the colour bar's time span the motion's duration.
    paths.append(plotting.plot_motion_strips(CheetahModel(), snapshots, out_dir / "fig5_motion.png",
                                             n_snapshots=FIG5_SNAPSHOTS, touchdowns=touchdowns,
                                             dt=fig["duration"] / (FIG5_SNAPSHOTS - 1)))
    f6 = fig["fig6"]
    paths.append(plotting.plot_forces_torques(fig["dt"], np.asarray(f6["U"], dtype=float),
                                              np.asarray(f6["GRF"], dtype=float), f6["torque_limit"],
                                              f6["friction"], out_dir / "fig6_forces_torques.png",
                                              stance=np.asarray(f6["stance"], dtype=bool), foot=0,
                                              title="AL + ReB: front-foot GRF (top) and joint torques (bottom)"))
    return paths


def paper_task2(data: dict, out_dir) -> list[Path]:
    """Paper Figs. 7 and 8 from a task-2 record's data (``experiments/paper_task2_sto.py``)."""
    out_dir = Path(out_dir)
    return [plotting.plot_sto_durations(data, out_dir / "fig7_durations.png"),
            plotting.plot_step_size(data["fig8"], out_dir / "fig8_step_size.png")]


def rl_curves(data: dict, out_dir) -> list[Path]:
    """``rl_curves.png``: each RL recipe's deterministic evaluations during training against env steps (log axis),
    the mean and 95 % interval over its training seeds, each seed dotted, and the MPC's return (an
    ``rl/curves`` record)."""
    from hsddp_gym.learning.reporting import curve_band

    plt = plotting._plt()
    fig, ax = plt.subplots(figsize=(9, 4.2))
    for i, (name, seeds) in enumerate(data["rows"].items()):
        curves = [(c["env_step"], c["mean_return"]) for c in seeds if len(c["env_step"]) >= 2]
        band = curve_band(curves)
        ax.plot(band["x"], band["mean"], color=f"C{i}", label=f"{name}: mean of {band['seeds']} seeds")
        ax.fill_between(band["x"], band["low"], band["high"], color=f"C{i}", alpha=0.25)
        for k, (x, y) in enumerate(curves):
            ax.plot(x, y, color=f"C{i}", lw=0.7, alpha=0.5, ls=":", label=f"{name}: each seed" if k == 0 else None)
    ax.axhline(data["mpc_return"], color="k", ls="--", lw=1, label=f"HS-DDP MPC {data['mpc_return']:.0f}")
    ax.set_xscale("log")
    ax.set_xlabel("env steps")
    ax.set_ylabel("episode return (deterministic evaluation)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    return [plotting._save(fig, Path(out_dir) / "rl_curves.png")]


def robustness(store, out_dir) -> list[Path]:
    """``robustness.png``: fall rate and speed error per condition of the suite (the columns of the
    ``robustness/suite`` table)."""
    from hsddp_gym.reports.tables.robustness import SUITE_LABELS, suite_columns

    conds, columns, _ = suite_columns(store)
    results = {SUITE_LABELS.get(k, k): v for k, v in columns.items()}
    path = Path(out_dir) / "robustness.png"
    plotting.plot_robustness(results, conds, path)
    return [path]


MOTION_SNAPSHOTS = 10
"""Snapshots per motion in ``motions_strips.png`` (a ``motions/*`` record keeps exactly these states)."""
MOTION_STATE_STRIDE = 5
"""Knots between the states a ``motions/*`` record keeps for ``motions_states.png``."""


def motion_figure_data(X: np.ndarray, dt: float) -> dict:
    """What [`motion_figures`][motion_figures] draws of one planned motion ``X (N+1, 14)`` with knot spacing ``dt`` [s],
    small enough for the results store: [`MOTION_SNAPSHOTS`][MOTION_SNAPSHOTS] evenly spaced configurations (7 columns)
    and the trunk height, pitch and forward speed every [`MOTION_STATE_STRIDE`][MOTION_STATE_STRIDE] knots (4
    significant digits)."""
    from hsddp_gym.core.conventions import IPITCH, IVX, IZ
    from hsddp_gym.reports.store import compact

    X = np.asarray(X, dtype=float)
    idx = np.linspace(0, X.shape[0] - 1, MOTION_SNAPSHOTS).astype(int)
    states = X[::MOTION_STATE_STRIDE]
    return {"dt": float(dt), "duration": float(dt * (X.shape[0] - 1)), "snapshots": compact(X[idx, :7]),
            "state_dt": float(dt * MOTION_STATE_STRIDE), "z": compact(states[:, IZ]),
            "pitch": compact(states[:, IPITCH]), "vx": compact(states[:, IVX])}


def _motion_arrays(fig: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(snapshots (S, 14), states (M, 14))`` of [`motion_figure_data`][motion_figure_data]'s dict (other columns
    zero)."""
    from hsddp_gym.core.conventions import IPITCH, IVX, IZ, NX

    snaps = np.asarray(fig["snapshots"], dtype=float)
    snap_x = np.zeros((snaps.shape[0], NX))
    snap_x[:, :7] = snaps
    z = np.asarray(fig["z"], dtype=float)
    states = np.zeros((z.shape[0], NX))
    states[:, IZ], states[:, IPITCH], states[:, IVX] = z, fig["pitch"], fig["vx"]
    return snap_x, states


def motion_figures(figs: dict, out_dir, prefix: str = "motions", terrains: dict | None = None,
                   states: bool = True, dpi: int = 110) -> list[Path]:
    """``<prefix>_strips.png`` (one strip of snapshots per motion) and, with ``states``, ``<prefix>_states.png``
    (trunk height, pitch and forward speed) from ``{label: motion_figure_data(...)}``; ``terrains`` ``{label:
    Terrain}`` the ground drawn under a strip (default flat); ``dpi`` of the strips."""
    from hsddp_gym.core.model import CheetahModel

    out_dir = Path(out_dir)
    snaps, series = {}, {}
    for label, fig in figs.items():
        snaps[label], series[label] = _motion_arrays(fig)
    durations = [fig["duration"] for fig in figs.values()]
    strips = plotting.plot_motion_strips(CheetahModel(), snaps, out_dir / f"{prefix}_strips.png",
                                         n_snapshots=MOTION_SNAPSHOTS, dt=max(durations) / (MOTION_SNAPSHOTS - 1),
                                         terrains=terrains, dpi=dpi)
    if not states:
        return [strips]
    step = next(iter(figs.values()))["state_dt"]
    return [strips, plotting.plot_states(series, step, out_dir / f"{prefix}_states.png")]


MOTION_ORDER = ("pronk", "stand_to_bound", "bound_pronk_bound", "bound_to_stop")


def motions(store, out_dir) -> list[Path]:
    """``motions_strips.png`` and ``motions_states.png``: every planned motion of the ``motions/*`` records."""
    figs = {}
    for name in MOTION_ORDER:
        rid = f"motions/{name}"
        if rid in store.ids():
            figs[name.replace("_", " ")] = store.data(rid)["figure"]
    return motion_figures(figs, out_dir) if figs else []


JUMP_ORDER = ("gap_jump", "box_jump", "backflip")
"""The ``motions/*`` records of ``jumps_strips.png``."""


def jumps(store, out_dir) -> list[Path]:
    """``jumps_strips.png``: the jumps and the backflip of the ``motions/*`` records, each over its terrain (a small
    PNG: strips only, 80 dpi)."""
    from hsddp_gym.core.terrain import Terrain

    figs, terrains = {}, {}
    for name in JUMP_ORDER:
        rid = f"motions/{name}"
        if rid in store.ids():
            d = store.data(rid)
            label = name.replace("_", " ")
            figs[label] = d["figure"]
            if "terrain" in d:
                t = d["terrain"]
                terrains[label] = Terrain(tuple(t["edges"]), tuple(t["levels"]), tuple(t["gaps"]))
    return motion_figures(figs, out_dir, prefix="jumps", terrains=terrains, states=False, dpi=80) if figs else []


FIGURE_DIR = "docs/figures"
"""Where the published figures live (relative to the repository's top folder)."""

POLICY_LABELS = {"mpc": "HS-DDP MPC", "heuristic": "contact-event heuristic"}
"""Legend names of the policies in the MPC-beside-heuristic figures."""


def generality(data: dict, out_dir) -> list[Path]:
    """``generality.png``: falls of 20 per condition, the MPC beside the heuristic, over the suite and the
    conditions the MPC was not built on (a ``robustness/generality`` record; the groups of its table)."""
    from hsddp_gym.reports.tables.robustness import generality_groups

    conds = list(data["conditions"])
    order = [c for _, members in generality_groups() for c in members if c in conds]
    order += [c for c in conds if c not in order]
    res = data["results"]
    policies = [p for p in ("mpc", "heuristic") if p in res]
    plt = plotting._plt()
    fig, ax = plt.subplots(figsize=(7.5, 0.22 * len(order) + 1.2))
    y = np.arange(len(order))
    height = 0.8 / max(len(policies), 1)
    for i, p in enumerate(policies):
        falls = [res[p][c]["falls"] for c in order]
        ax.barh(y + (i - (len(policies) - 1) / 2) * height, falls, height=height, color=f"C{i}",
                label=POLICY_LABELS.get(p, p))
    episodes = max(res[p][c]["episodes"] for p in policies for c in order)
    ax.axvline(1, color="k", ls=":", lw=0.8, label="1 fall")
    ax.set_yticks(y, order, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlim(0, episodes)
    ax.set_xlabel(f"falls of {episodes} (seeds {data['seeds'][0]}-{data['seeds'][-1]})")
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(axis="x", alpha=0.3)
    path = Path(out_dir) / "generality.png"
    plotting._save(fig, path, dpi=90)
    return [path]


def pushes(data: dict, out_dir) -> list[Path]:
    """``pushes.png``: the fall rate under each push law with its 95 % Wilson interval, the MPC beside the heuristic
    (a ``robustness/pushes`` record)."""
    from hsddp_gym.reports.tables.robustness import wilson_interval

    conds = list(data["conditions"])
    res = data["results"]
    policies = [p for p in ("mpc", "heuristic") if p in res]
    plt = plotting._plt()
    fig, ax = plt.subplots(figsize=(6.0, 2.8))
    x = np.arange(len(conds))
    width = 0.8 / max(len(policies), 1)
    for i, p in enumerate(policies):
        cells = [res[p][c] for c in conds]
        rate = np.array([100.0 * c["falls"] / c["episodes"] for c in cells])
        bounds = np.array([wilson_interval(c["falls"], c["episodes"]) for c in cells]) * 100.0
        err = np.vstack([rate - bounds[:, 0], bounds[:, 1] - rate])
        ax.bar(x + (i - (len(policies) - 1) / 2) * width, rate, width=width, color=f"C{i}", yerr=err, capsize=3,
               label=POLICY_LABELS.get(p, p))
    ax.axhline(5.0, color="k", ls=":", lw=0.8, label="1 fall in 20")
    ax.set_xticks(x, conds, fontsize=8)
    ax.set_ylabel("falls [%] (95 % interval)")
    episodes = res[policies[0]][conds[0]]["episodes"]
    ax.set_title(f"{episodes} episodes per push law (seeds {data['seeds'][0]}-{data['seeds'][-1]})", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(axis="y", alpha=0.3)
    path = Path(out_dir) / "pushes.png"
    plotting._save(fig, path, dpi=90)
    return [path]


FIGURES: dict[str, Callable[[dict, Path], list[Path]]] = {
    "paper/task1": paper_task1,
    "paper/sto": paper_task2,
    "rl/curves": rl_curves,
    "robustness/generality": generality,
    "robustness/pushes": pushes,
}
"""``{record id: drawing function of the record's data}``; each writes its figures into the folder it is given."""

STORE_FIGURES: list[Callable] = [robustness, motions, jumps]
"""Figures drawn from several records: functions of the store and the folder."""


def regenerate(store, root) -> list[Path]:
    """Draw every figure of [`FIGURES`][FIGURES] from ``store`` into ``root/docs/figures``.

    Returns:
        the paths written.
    """
    written = []
    out = Path(root) / FIGURE_DIR
    for rid, draw in FIGURES.items():
        written += draw(store.data(rid), out)
    for draw in STORE_FIGURES:
        written += draw(store, out)
    return written

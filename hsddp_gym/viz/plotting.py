"""Matplotlib figures (off-screen, Agg): motion snapshots, states, solver convergence, forces and torques.

Needs the ``viz`` extra (matplotlib). Every function saves a PNG atomically and returns its path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hsddp_gym.core.conventions import FOOT_NAMES, IPITCH, IVX, IZ, NQ, U_NAMES
from hsddp_gym.util.io import atomic_path


def _plt():
    try:
        import matplotlib
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("plots need matplotlib: pip install 'hsddp_gym[viz]'") from exc
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` as a PNG (atomically). With Pillow installed the image is stored with an adaptive
    256-colour palette (plots are mostly flat colours: a third to a half of the RGBA size, the same picture to the
    eye), so that the figures of the docs stay small."""
    import io

    plt = _plt()
    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, bbox_inches="tight", format="png")
    plt.close(fig)
    data = buf.getvalue()
    try:
        from PIL import Image
    except ImportError:
        pass
    else:
        with Image.open(io.BytesIO(data)) as img:
            out = io.BytesIO()
            img.convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
                out, format="png", optimize=True)
            data = out.getvalue()
    with atomic_path(path, suffix=".png") as tmp:
        Path(tmp).write_bytes(data)
    return Path(path)


def draw_robot(ax, robot, q, color="C0", alpha=1.0, lw=2.0) -> None:
    """Draw the planar robot at configuration ``q`` (7,) as a stick figure on a matplotlib axis."""
    pts = robot.link_points(np.asarray(q)[:NQ])
    hips = pts[:, 0]
    ax.plot(hips[:, 0], hips[:, 1], "-", color=color, lw=lw * 2, alpha=alpha, solid_capstyle="round")
    for foot in range(2):
        leg = pts[foot, :3]
        ax.plot(leg[:, 0], leg[:, 1], "-o", color=color, lw=lw, ms=2.5, alpha=alpha)


def plot_motion_strips(robot, trajectories: dict, path, n_snapshots: int = 14, touchdowns: dict | None = None,
                       dt: float | None = None, terrains: dict | None = None, dpi: int = 110) -> Path:
    """Paper Fig. 5: one strip of snapshots per trajectory (``{label: X (N+1, 14)}``), coloured by time (the
    colour bar: time [s] with the knot spacing ``dt``, else the fraction of the motion).

    ``touchdowns``: ``{label: [(x, height), ...]}`` landing points; where a foot "lands" above or below
    z = 0 (the switching constraint violated), a red "virtual ground" segment is drawn at that height.
    ``terrains``: ``{label: Terrain}`` ground profiles ([`Terrain`][hsddp_gym.core.terrain.Terrain]) drawn instead of
    the line z = 0 (a gap as a break in the ground). ``dpi``: of the PNG.
    """
    plt = _plt()
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    labels = list(trajectories)
    fig, axes = plt.subplots(len(labels), 1, figsize=(14, 2.3 * len(labels)), squeeze=False)
    for ax, label in zip(axes[:, 0], labels):
        X = trajectories[label]
        idx = np.linspace(0, X.shape[0] - 1, n_snapshots).astype(int)
        for j, k in enumerate(idx):
            draw_robot(ax, robot, X[k], color=plt.cm.viridis(j / max(len(idx) - 1, 1)), alpha=0.9, lw=1.6)
        xmin, xmax = X[:, 0].min() - 0.4, X[:, 0].max() + 0.4
        terrain = (terrains or {}).get(label)
        if terrain is None or terrain.is_flat:
            ax.axhline(0.0, color="k", lw=1.5)
        else:
            bounds = [xmin] + [e for e in terrain.edges if xmin < e < xmax] + [xmax]
            for a, b in zip(bounds[:-1], bounds[1:]):
                mid = 0.5 * (a + b)
                if not terrain.over_gap(mid):
                    h = terrain.height(mid)
                    ax.fill_between([a, b], [h, h], [-0.1, -0.1], color="0.8", lw=0)
                    ax.plot([a, b], [h, h], "k-", lw=1.5)
        for x_td, z_td in (touchdowns or {}).get(label, []):
            if abs(z_td) > 2e-3:
                ax.plot([x_td - 0.06, x_td + 0.06], [z_td, z_td], "r-", lw=2)
        ax.set_xlim(xmin, xmax)
        top = max(float(robot.link_points(X[k, :7])[:, :, 1].max()) for k in idx)  # a flip's apex: above 0.5 m
        ax.set_ylim(-0.1, max(0.55, top + 0.05))
        ax.set_aspect("equal")
        ax.set_title(label, fontsize=10, loc="left")
        ax.set_ylabel("z [m]")
    axes[-1, 0].set_xlabel("x [m]")
    fig.subplots_adjust(hspace=0.45)
    n_knots = max(X.shape[0] for X in trajectories.values()) - 1
    span = n_knots * dt if dt is not None else 1.0
    bar = fig.colorbar(ScalarMappable(norm=Normalize(0.0, span), cmap=plt.cm.viridis), ax=axes[:, 0].tolist(),
                       fraction=0.02, pad=0.01)
    bar.set_label("t [s] (snapshot colour)" if dt is not None else "fraction of the motion (snapshot colour)")
    return _save(fig, path, dpi=dpi)


def plot_states(trajectories: dict, dt: float, path, target_speed: float | None = None) -> Path:
    """Trunk height, pitch and forward speed against time for ``{label: X (N+1, 14)}``."""
    plt = _plt()
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for label, X in trajectories.items():
        t = dt * np.arange(X.shape[0])
        axes[0].plot(t, X[:, IZ], label=label)
        axes[1].plot(t, X[:, IPITCH], label=label)
        axes[2].plot(t, X[:, IVX], label=label)
    if target_speed is not None:
        axes[2].axhline(target_speed, color="k", ls="--", lw=1, label="target")
    axes[0].set_ylabel("trunk z [m]")
    axes[1].set_ylabel("pitch [rad]")
    axes[2].set_ylabel("dx/dt [m/s]")
    axes[2].set_xlabel("t [s]")
    axes[0].legend(fontsize=8, ncol=4)
    if target_speed is not None:
        axes[2].legend(fontsize=8, ncol=4)  # with the dashed target line
    return _save(fig, path)


def convergence_series(solution) -> dict:
    """What [`plot_convergence`][plot_convergence] draws of a
    [`Solution`][hsddp_gym.planners.optimizer.solution.Solution]: per logged DDP iteration its index, penalty-free cost,
    sum g^2, and whether an AL iteration starts there (lists)."""
    events = np.array([r.event for r in solution.log])
    return {"ddp_iteration": solution.log_array("ddp_iteration").tolist(),
            "cost": solution.log_array("cost").tolist(),
            "switching_violation": solution.log_array("switching_violation").tolist(),
            "al_start": ((events == "init") | (events == "al_update")).tolist()}


def plot_convergence(solutions: dict, path) -> Path:
    """Paper Fig. 4: penalty-free cost and sum g^2 per DDP iteration, markers at the AL iterations'
    starts (``{label: Solution}``, or ``{label: convergence_series(Solution)}``)."""
    plt = _plt()
    series = {label: s if isinstance(s, dict) else convergence_series(s) for label, s in solutions.items()}
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for j, (label, ser) in enumerate(series.items()):
        it = np.asarray(ser["ddp_iteration"], dtype=float)
        cost = np.asarray(ser["cost"], dtype=float)
        viol = np.asarray(ser["switching_violation"], dtype=float)
        starts = np.asarray(ser["al_start"], dtype=bool)
        color = f"C{j}"
        axes[0].plot(it, cost, "-", color=color, label=label)
        axes[1].semilogy(it, np.maximum(viol, 1e-12), "-", color=color, label=label)
        axes[0].plot(it[starts], cost[starts], "s", color=color, ms=6, mfc="none")
        axes[1].semilogy(it[starts], np.maximum(viol[starts], 1e-12), "o", color=color, ms=6, mfc="none")
    axes[1].axhline(1e-4, color="k", ls="--", lw=1, label=r"$\epsilon_{AL}$ = 1e-4")
    axes[0].set_ylabel("cost (eq. 18)")
    axes[0].set_yscale("log")
    axes[1].set_ylabel(r"$\sum g^2$ [m$^2$]")
    axes[1].set_xlabel("DDP iteration (markers: start of an AL iteration)")
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=8)
    _pad_log_limits(axes[0], [np.asarray(ser["cost"], dtype=float) for ser in series.values()])
    _pad_log_limits(axes[1], [np.maximum(np.asarray(ser["switching_violation"], dtype=float), 1e-12)
                              for ser in series.values()] + [np.array([1e-4])])
    n_it = max((max(ser["ddp_iteration"]) for ser in series.values() if ser["ddp_iteration"]), default=1)
    axes[1].set_xlim(-0.04 * n_it - 0.5, 1.04 * n_it + 0.5)  # room for the markers at both ends
    return _save(fig, path)


def _pad_log_limits(ax, series, pad_decades: float = 0.08) -> None:
    """Log-scale y limits spanning every value of ``series`` with ``pad_decades`` of the span on both sides, so
    markers at the extremes are drawn whole."""
    values = np.concatenate([np.asarray(v, dtype=float).ravel() for v in series]) if series else np.array([1.0])
    values = values[np.isfinite(values) & (values > 0)]
    if values.size == 0:
        return
    lo, hi = np.log10(values.min()), np.log10(values.max())
    pad = max(pad_decades * (hi - lo), 0.05)
    ax.set_ylim(10 ** (lo - pad), 10 ** (hi + pad))


def plot_forces_torques(dt: float, U: np.ndarray, GRF: np.ndarray, torque_limit: float, friction: float, path,
                        stance: np.ndarray | None = None, foot: int = 0, title: str = "") -> Path:
    """Paper Fig. 6: normal and tangential force of one foot with the friction bound, and the joint torques
    with their limit."""
    plt = _plt()
    t = dt * np.arange(U.shape[0])
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    fx, fz = GRF[:, 2 * foot], GRF[:, 2 * foot + 1]
    if stance is not None:
        fx = np.where(stance[:, foot], fx, np.nan)
        fz = np.where(stance[:, foot], fz, np.nan)
    axes[0].plot(t, fz, label=f"{FOOT_NAMES[foot]} normal $f_z$")
    axes[0].plot(t, fx, label=f"{FOOT_NAMES[foot]} tangential $f_x$")
    axes[0].plot(t, friction * fz, "k--", lw=1, label=r"$\pm\mu f_z$")
    axes[0].plot(t, -friction * fz, "k--", lw=1)
    axes[0].axhline(0.0, color="grey", lw=0.8)
    axes[0].set_ylabel("GRF [N]")
    axes[0].legend(fontsize=8)
    for j in range(U.shape[1]):
        axes[1].plot(t, U[:, j], label=U_NAMES[j])
    axes[1].axhline(torque_limit, color="k", ls="--", lw=1)
    axes[1].axhline(-torque_limit, color="k", ls="--", lw=1, label=f"±{torque_limit:g} N m limit")
    axes[1].set_ylabel("torque [N m]")
    axes[1].set_xlabel("t [s]")
    axes[1].legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))  # outside: clear of the limits
    if title:
        axes[0].set_title(title, fontsize=10)
    return _save(fig, path)


def plot_sto_durations(summary: dict, path) -> Path:
    """Paper Fig. 7: the mode durations before STO and after HS-DDP and the open-loop method (a task-2 summary)."""
    plt = _plt()
    labels = ["BS", "FL1", "FS", "FL2"]
    init = 1e3 * np.array(summary["hsddp"]["initial_durations"])
    bars = {"initial": init, "HS-DDP": 1e3 * np.array(summary["hsddp"]["mode_durations"]),
            "open loop [24]": 1e3 * np.array(summary["open-loop"]["mode_durations"])}
    fig, ax = plt.subplots(figsize=(7, 4))
    width = 0.27
    for j, (name, vals) in enumerate(bars.items()):
        ax.bar(np.arange(4) + (j - 1) * width, vals, width, label=name)
    ax.set_xticks(np.arange(4), labels)
    ax.set_ylabel("mode duration [ms]")
    ax.set_title(f"total: initial {init.sum():.1f} ms, HS-DDP {bars['HS-DDP'].sum():.1f} ms, "
                 f"open loop {bars['open loop [24]'].sum():.1f} ms", fontsize=9)
    ax.legend()
    return _save(fig, path)


def plot_step_size(study: dict, path) -> Path:
    """Paper Fig. 8: actual and predicted change of the objective against the step size.

    Args:
        study: the result of [`hsddp_gym.planners.tasks.fig8_study`][hsddp_gym.planners.tasks.fig8_study].
        path: the PNG to write.
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    s = np.array(study["steps"])
    colors = {"durations": ("r", r"$\epsilon=0,\ \epsilon_z=s$"), "control": ("m", r"$\epsilon=s,\ \epsilon_z=0$"),
              "both": ("b", r"$\epsilon=\epsilon_z=s$")}
    for case, (c, label) in colors.items():
        ax.plot(s, study[case]["actual"], "-", color=c, label=f"{label} actual")
        ax.plot(s, study[case]["predicted"], "--", color=c, label=f"{label} predicted")
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.set_yscale("symlog", linthresh=1.0)  # the duration step's actual change grows by orders of magnitude
    ax.set_xlabel("step size s")
    ax.set_ylabel("change of the objective (symlog)")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_robustness(results: dict, conditions, path) -> bool:
    """Fall rate and speed error per condition and policy (``results[policy][condition]``: a cell with
    ``falls``, ``episodes``, ``speed_error``). False when matplotlib is missing."""
    try:
        plt = _plt()
    except ImportError:  # matplotlib is in the viz extra
        return False
    labels = list(results)
    x = np.arange(len(conditions))
    w = 0.8 / len(labels)
    fig, (a, b) = plt.subplots(2, 1, figsize=(max(8, 0.9 * len(conditions)), 6.5), sharex=True)
    for i, label in enumerate(labels):
        cells = [results[label].get(c) for c in conditions]
        falls = [np.nan if c is None else c["falls"] / c["episodes"] for c in cells]
        err = [np.nan if c is None or c.get("speed_error") is None else 100 * c["speed_error"] for c in cells]
        a.bar(x + i * w - 0.4 + w / 2, falls, w, label=label)
        b.bar(x + i * w - 0.4 + w / 2, err, w, label=label)
    a.set_ylabel("fall rate")
    a.axhline(0.05, color="k", ls="--", lw=0.8)
    a.legend()
    b.set_ylabel("speed error [%]")
    for y in (-10, 10):
        b.axhline(y, color="k", ls="--", lw=0.8)
    b.set_xticks(x)
    b.set_xticklabels(conditions, rotation=35, ha="right")
    fig.tight_layout()
    _save(fig, path)
    return True

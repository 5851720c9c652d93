"""The plan figures say what they show: motion.png's colours have a colour bar (time), the dashed target line
has a legend entry, convergence markers at the extremes are inside the axes, the torque legend leaves the
±33 N m limit lines visible."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from hsddp_gym.planners.tasks import plan_bounding  # noqa: E402
from hsddp_gym.viz import plotting  # noqa: E402


@pytest.fixture(scope="module")
def plan():
    return plan_bounding("al-reb", cycles=1)


@pytest.fixture
def figures(monkeypatch):
    """The figures the plotting functions save, kept open (they are closed after the test)."""
    import matplotlib.pyplot as plt

    kept = []
    monkeypatch.setattr(plotting, "_save", lambda fig, path, **_: kept.append(fig) or path)
    yield kept
    for fig in kept:
        plt.close(fig)


def test_motion_strip_colours_have_a_time_colour_bar(plan, figures, tmp_path):
    pr = plan.problem
    plotting.plot_motion_strips(pr.dynamics.robot, {"al-reb": plan.X}, tmp_path / "m.png", dt=pr.dt)
    fig = figures[-1]
    bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert len(bars) == 1
    assert "t [s]" in bars[0].get_ylabel()
    assert bars[0].get_ylim() == pytest.approx((0.0, pr.n_knots * pr.dt))


def test_the_dashed_target_line_is_in_a_legend(plan, figures, tmp_path):
    plotting.plot_states({"plan": plan.X}, plan.problem.dt, tmp_path / "s.png", target_speed=1.0)
    speed_ax = figures[-1].axes[2]
    legend = speed_ax.get_legend()
    assert legend is not None and "target" in [t.get_text() for t in legend.get_texts()]


def test_convergence_markers_are_inside_the_axes(plan, figures, tmp_path):
    plotting.plot_convergence({"al-reb": plan.solution}, tmp_path / "c.png")
    fig = figures[-1]
    fig.canvas.draw()
    for ax in fig.axes:
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        for line in ax.get_lines():
            if line.get_marker() in ("s", "o"):
                x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
                # the marker's centre at least ~half a marker (6 pt) from every edge, in display space
                pts = ax.transData.transform(np.c_[x, y])
                box = ax.get_window_extent()
                half = line.get_markersize() / 2 * fig.dpi / 72
                assert np.all(pts[:, 0] - half >= box.x0 - 1e-6) and np.all(pts[:, 0] + half <= box.x1 + 1e-6)
                assert np.all(pts[:, 1] - half >= box.y0 - 1e-6) and np.all(pts[:, 1] + half <= box.y1 + 1e-6)
                assert np.all((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1))


def test_torque_legend_does_not_cover_the_limit_lines(plan, figures, tmp_path):
    pr = plan.problem
    plotting.plot_forces_torques(pr.dt, plan.U, plan.GRF, pr.constraints.torque_limit, pr.constraints.friction,
                                 tmp_path / "f.png", stance=pr.stance)
    fig = figures[-1]
    fig.canvas.draw()
    ax = fig.axes[1]
    legend = ax.get_legend()
    assert "±33 N m limit" in [t.get_text() for t in legend.get_texts()]
    lb, ab = legend.get_window_extent(), ax.get_window_extent()
    # outside the plotting area, so neither limit line (nor any curve) is hidden
    assert lb.x0 >= ab.x1 or lb.y0 >= ab.y1 or lb.y1 <= ab.y0 or lb.x1 <= ab.x0

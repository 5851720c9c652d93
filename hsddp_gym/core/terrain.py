"""Planar terrain for the planner: a piecewise-constant ground height ``h(x)`` [m] along the world x axis.

The one place that defines terrain. The conventions' ground is the plane ``z = 0`` (:mod:`hsddp_gym.core.conventions`);
a :class:`Terrain` raises or lowers it on intervals of x:

* :meth:`Terrain.flat` (the default): ``h(x) = 0`` everywhere;
* :meth:`Terrain.step`: ``h = height`` for ``x >= x0`` (a step up or down);
* :meth:`Terrain.box`: ``h = height`` for ``x0 <= x < x1`` (a box to jump onto);
* :meth:`Terrain.gap`: no ground for ``x0 <= x < x1`` (a foot may not land there).

A gap has no ground at all; for the planner it is a floor :attr:`Terrain.gap_depth` below the neighbouring ground
(finite, so the switching constraint ``g = foot_z - h(foot_x)`` and its derivative stay finite; the legs cannot reach
that deep, so a plan that lands a foot there breaks its switching constraint), and :meth:`Terrain.over_gap` tells
where it is (``motion_limits`` checks that no stance foot is over a gap).

Edges belong to the segment on their right: ``h(edge) = h(edge + 0)``. Piecewise constant, ``dh/dx = 0`` wherever x
is not exactly on an edge, so the derivative of the switching constraint of a landing foot is the derivative of its
height, ``dg/dq = d foot_z / dq``; at an edge ``h`` jumps and the planner uses the same one-sided derivative.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

import numpy as np

GAP_DEPTH = 1.0
"""How far below the neighbouring ground the planner puts the floor of a gap [m] (more than a leg's reach)."""


def _real(value, name: str, *, positive: bool = False) -> float:
    """``value`` as a finite float, naming ``name`` in the error (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise ValueError(f"{name} must be a finite number [m], got {value!r}")
    if positive and float(value) <= 0.0:
        raise ValueError(f"{name} must be > 0 [m], got {value!r}")
    return float(value)


@dataclasses.dataclass(frozen=True)
class Terrain:
    """A piecewise-constant ground profile along x.

    Attributes:
        edges: ``(k,)`` strictly increasing x of the height changes [m].
        levels: ``(k + 1,)`` ground height of each segment [m]: ``levels[0]`` for ``x < edges[0]``, ``levels[i]``
            for ``edges[i-1] <= x < edges[i]``, ``levels[k]`` for ``x >= edges[-1]``. A gap segment's level is its
            floor for the planner.
        gaps: ``(k + 1,)`` True for a segment without ground (a gap).
    """

    edges: tuple[float, ...] = ()
    levels: tuple[float, ...] = (0.0,)
    gaps: tuple[bool, ...] = (False,)

    def __post_init__(self) -> None:
        edges = tuple(_real(e, f"edges[{i}]") for i, e in enumerate(self.edges))
        levels = tuple(_real(v, f"levels[{i}]") for i, v in enumerate(self.levels))
        gaps = tuple(self.gaps)
        if any(b <= a for a, b in zip(edges, edges[1:])):
            raise ValueError(f"edges must be strictly increasing [m], got {list(edges)}")
        if len(levels) != len(edges) + 1:
            raise ValueError(f"levels must hold len(edges) + 1 = {len(edges) + 1} heights [m], got {len(levels)}")
        if len(gaps) != len(levels) or not all(isinstance(g, (bool, np.bool_)) for g in gaps):
            raise ValueError(f"gaps must hold {len(levels)} bools (one per segment), got {self.gaps!r}")
        object.__setattr__(self, "edges", edges)
        object.__setattr__(self, "levels", levels)
        object.__setattr__(self, "gaps", tuple(bool(g) for g in gaps))
        object.__setattr__(self, "_edges", np.array(edges, dtype=np.float64))
        object.__setattr__(self, "_levels", np.array(levels, dtype=np.float64))
        object.__setattr__(self, "_gaps", np.array(self.gaps, dtype=bool))

    # ------------------------------------------------------------------ factories
    @classmethod
    def flat(cls) -> Terrain:
        """The conventions' ground: ``h(x) = 0`` everywhere."""
        return cls()

    @classmethod
    def step(cls, x0: float, height: float) -> Terrain:
        """Ground at 0 for ``x < x0`` [m] and at ``height`` [m] (up if > 0, down if < 0) for ``x >= x0``."""
        return cls((_real(x0, "x0"),), (0.0, _real(height, "height")), (False, False))

    @classmethod
    def box(cls, x0: float, x1: float, height: float) -> Terrain:
        """A box of ``height`` > 0 [m] on the ground from ``x0`` to ``x1 > x0`` [m]."""
        a, b = _real(x0, "x0"), _real(x1, "x1")
        if b <= a:
            raise ValueError(f"x1 must be > x0 (the box's far edge after its near one) [m], got x0={x0!r}, x1={x1!r}")
        return cls((a, b), (0.0, _real(height, "height", positive=True), 0.0), (False, False, False))

    @classmethod
    def gap(cls, x0: float, x1: float, depth: float = GAP_DEPTH) -> Terrain:
        """No ground from ``x0`` to ``x1 > x0`` [m]; for the planner its floor is ``depth`` > 0 [m] below 0."""
        a, b = _real(x0, "x0"), _real(x1, "x1")
        if b <= a:
            raise ValueError(f"x1 must be > x0 (the gap's far edge after its near one) [m], got x0={x0!r}, x1={x1!r}")
        return cls((a, b), (0.0, -_real(depth, "depth", positive=True), 0.0), (False, True, False))

    # ------------------------------------------------------------------ queries
    @property
    def is_flat(self) -> bool:
        """True when ``h(x) = 0`` everywhere (no gap)."""
        return not any(self.gaps) and all(v == 0.0 for v in self.levels)

    def _segments(self, xs: np.ndarray) -> np.ndarray:
        return np.searchsorted(self._edges, xs, side="right")

    def height(self, x: float) -> float:
        """Ground height ``h(x)`` [m] at ``x`` [m] (a gap: its floor for the planner)."""
        x = _real(x, "x")
        return float(self._levels[int(np.searchsorted(self._edges, x, side="right"))])

    def heights(self, xs) -> np.ndarray:
        """Vectorised :meth:`height`: ``xs`` any shape [m] -> heights of the same shape [m]."""
        xs = np.asarray(xs, dtype=np.float64)
        if not np.all(np.isfinite(xs)):
            raise ValueError("xs must be finite [m]")
        return self._levels[self._segments(xs)]

    def over_gap(self, xs) -> np.ndarray:
        """``xs`` any shape [m] -> bools of the same shape: True where there is no ground (inside a gap)."""
        xs = np.asarray(xs, dtype=np.float64)
        if not np.all(np.isfinite(xs)):
            raise ValueError("xs must be finite [m]")
        return self._gaps[self._segments(xs)]

    def describe(self) -> str:
        """The profile in words, e.g. ``"gap 0.50..0.80 m"`` or ``"flat"``."""
        if self.is_flat:
            return "flat"
        parts = []
        bounds = (-math.inf,) + self.edges + (math.inf,)
        for i, (lvl, gap) in enumerate(zip(self.levels, self.gaps)):
            if gap:
                parts.append(f"gap {bounds[i]:.2f}..{bounds[i + 1]:.2f} m")
            elif lvl != 0.0:
                parts.append(f"ground at {lvl:+.2f} m for x in [{bounds[i]:.2f}, {bounds[i + 1]:.2f})")
        return "; ".join(parts)


FLAT = Terrain()
"""The flat ground ``h = 0``."""


def check_terrain(terrain, name: str = "terrain") -> Terrain | None:
    """``terrain`` if it is a :class:`Terrain` or None; TypeError naming ``name`` otherwise."""
    if terrain is not None and not isinstance(terrain, Terrain):
        raise TypeError(f"{name} must be a Terrain or None, got {type(terrain).__name__}")
    return terrain


__all__ = ["GAP_DEPTH", "FLAT", "Terrain", "check_terrain"]

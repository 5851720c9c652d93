"""Planar terrain for the planner: a piecewise-constant ground height ``h(x)`` [m] along the world x axis.

The one place that defines terrain. The conventions' ground is the plane ``z = 0``
([`hsddp_gym.core.conventions`][hsddp_gym.core.conventions]); a [`Terrain`][Terrain] raises or lowers it on intervals of
x:

* [`Terrain.flat`][Terrain.flat] (the default): ``h(x) = 0`` everywhere;
* [`Terrain.step`][Terrain.step]: ``h = height`` for ``x >= x0`` (a step up or down);
* [`Terrain.box`][Terrain.box]: ``h = height`` for ``x0 <= x < x1`` (a box to jump onto);
* [`Terrain.gap`][Terrain.gap]: no ground for ``x0 <= x < x1`` (a foot may not land there).

A gap has no ground at all; for the planner it is a floor `Terrain.gap_depth` below the neighbouring ground
(finite, so the switching constraint ``g = foot_z - h(foot_x)`` and its derivative stay finite; the legs cannot reach
that deep, so a plan that lands a foot there breaks its switching constraint), and
[`Terrain.over_gap`][Terrain.over_gap] tells where it is (``motion_limits`` checks that no stance foot is over a gap).

Edges belong to the segment on their right: ``h(edge) = h(edge + 0)``. Piecewise constant, ``dh/dx = 0`` wherever x
is not exactly on an edge, so the derivative of the switching constraint of a landing foot is the derivative of its
height, ``dg/dq = d foot_z / dq``; at an edge ``h`` jumps and the planner uses the same one-sided derivative.

Slopes: a segment may also rise linearly, ``h(x) = levels[i] + slopes[i] (x - a_i)`` with ``a_i`` its left edge
(``edges[0]`` for the first segment, 0 when there is no edge); [`Terrain.ramp`][Terrain.ramp] builds one. The planner's
switching constraints differentiate a slope's ``h`` (``dg/dq = d foot_z / dq - dh/dx d foot_x / dq``; the jumps use
level ground).

The simulated surface (``hsddp_gym/Bounding-v0``'s ``terrain=``,
[`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact])
--------------------------------------------------------------------------------------------------------
The contact simulation needs a surface with a normal everywhere, so it uses the *continuous* piecewise-linear
profile [`Terrain.surface_vertices`][Terrain.surface_vertices]: ``h(x)`` itself, except that each jump of ``h`` at an
edge ``e`` becomes a steep ramp (a riser) over ``[e - riser, e]`` ([`RISER_WIDTH`][RISER_WIDTH], 1 mm: a 3 cm step is a
88 degree wall whose normal points backward, so a foot that runs into it is stopped by it, with friction along it); a
gap is a drop of `gap_depth` to its floor, with two risers. Beyond the outermost vertices
([`SURFACE_EXTENT`][SURFACE_EXTENT] from the outermost edges) the surface is level.
[`Terrain.surface_heights`][Terrain.surface_heights] and [`Terrain.surface_normals`][Terrain.surface_normals] evaluate
it. [`Terrain.support_heights`][Terrain.support_heights] is the ground a trunk stands over, with a gap bridged at the
level of its near edge (the env's fall rule: the trunk falling into a gap is a fall). [`Terrain.sample`][Terrain.sample]
draws seeded random profiles. """

from __future__ import annotations

import bisect
import dataclasses
import math
import numbers

import numpy as np

GAP_DEPTH = 1.0
"""How far below the neighbouring ground the planner puts the floor of a gap [m] (more than a leg's reach)."""
RISER_WIDTH = 1e-3
"""Horizontal width [m] of the steep ramp that stands for a jump of ``h`` in the simulated surface."""
SURFACE_EXTENT = 1000.0
"""The simulated surface's outermost vertices lie this far [m] beyond the outermost edges (level beyond)."""
SAMPLE_KINDS = ("steps", "slopes", "mixed")
"""Kinds of [`Terrain.sample`][Terrain.sample]."""


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
        slopes: ``(k + 1,)`` ``dh/dx`` of each segment (default: all 0, piecewise constant); segment ``i`` is
            ``h(x) = levels[i] + slopes[i] (x - a_i)``, ``a_i`` its left edge (``edges[0]`` for the first segment,
            0 without edges). A gap's slope must be 0.
    """

    edges: tuple[float, ...] = ()
    levels: tuple[float, ...] = (0.0,)
    gaps: tuple[bool, ...] = (False,)
    slopes: tuple[float, ...] | None = None

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
        slopes = (0.0,) * len(levels) if self.slopes is None else tuple(self.slopes)
        if len(slopes) != len(levels):
            raise ValueError(f"slopes must hold {len(levels)} numbers (one per segment), got {len(slopes)}")
        slopes = tuple(_real(v, f"slopes[{i}]") for i, v in enumerate(slopes))
        if any(g and sl != 0.0 for g, sl in zip(gaps, slopes)):
            raise ValueError(f"slopes must be 0 on a gap segment, got slopes={list(slopes)}, gaps={list(gaps)}")
        object.__setattr__(self, "edges", edges)
        object.__setattr__(self, "levels", levels)
        object.__setattr__(self, "gaps", tuple(bool(g) for g in gaps))
        object.__setattr__(self, "slopes", slopes)
        object.__setattr__(self, "_edges", np.array(edges, dtype=np.float64))
        object.__setattr__(self, "_levels", np.array(levels, dtype=np.float64))
        object.__setattr__(self, "_gaps", np.array(self.gaps, dtype=bool))
        object.__setattr__(self, "_slopes", np.array(slopes, dtype=np.float64))
        anchors = (edges[0] if edges else 0.0,) + edges
        object.__setattr__(self, "_anchors", np.array(anchors, dtype=np.float64))
        object.__setattr__(self, "_anchors_t", anchors)
        bridged = list(levels)  # each segment's support level: a gap bridged at its near edge's level
        for i, gap in enumerate(gaps):
            if gap:
                if i > 0 and not gaps[i - 1]:
                    bridged[i] = levels[i - 1] + slopes[i - 1] * (edges[i - 1] - anchors[i - 1])
                elif i + 1 < len(levels):
                    bridged[i] = levels[i + 1]
        object.__setattr__(self, "_bridged_t", tuple(bridged))
        object.__setattr__(self, "_bridged", np.array(bridged, dtype=np.float64))
        object.__setattr__(self, "_surface", None)

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

    @classmethod
    def ramp(cls, x0: float, x1: float, slope: float) -> Terrain:
        """Ground at 0 for ``x < x0``, rising with ``slope`` (``dh/dx``, down if < 0) from ``x0`` to ``x1 > x0``
        [m], then level at ``slope (x1 - x0)``."""
        a, b = _real(x0, "x0"), _real(x1, "x1")
        if b <= a:
            raise ValueError(f"x1 must be > x0 (the ramp's top after its foot) [m], got x0={x0!r}, x1={x1!r}")
        sl = _real(slope, "slope")
        return cls((a, b), (0.0, 0.0, sl * (b - a)), (False,) * 3, (0.0, sl, 0.0))

    @classmethod
    def sample(cls, rng: np.random.Generator, kind: str = "mixed", *, start: float = 0.6, length: float = 8.0,
               segment_length=(0.3, 0.8), max_step: float = 0.03, max_slope: float = 0.1,
               max_level: float = 0.15) -> Terrain:
        """A random profile drawn from ``rng`` (a ``numpy.random.Generator``; the same state gives the same profile).

        Level ground at 0 for ``x < start`` [m] (where the robot starts), then segments of lengths drawn
        ``U(segment_length)`` [m] until ``start + length`` [m], level beyond. Each segment is, by ``kind``:

        * ``"steps"``: level, ``U(-max_step, max_step)`` [m] above or below the previous one's end (a step);
        * ``"slopes"``: continuous with the previous one, with slope ``dh/dx ~ U(-max_slope, max_slope)``;
        * ``"mixed"``: either (probability 1/2 each).

        A level that would leave ``[-max_level, max_level]`` [m] is mirrored back inside it (a step) or the slope's
        sign flipped (a slope), so the profile never drifts far from 0."""
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if kind not in SAMPLE_KINDS:
            raise ValueError(f"kind must be one of {list(SAMPLE_KINDS)}, got {kind!r}")
        start = _real(start, "start")
        length = _real(length, "length", positive=True)
        if not isinstance(segment_length, (tuple, list)) or len(segment_length) != 2:
            raise TypeError(f"segment_length must be a pair (low, high) [m], got {segment_length!r}")
        lo = _real(segment_length[0], "segment_length[0]", positive=True)
        hi = _real(segment_length[1], "segment_length[1]", positive=True)
        if hi < lo or lo <= 2 * RISER_WIDTH:
            raise ValueError(f"segment_length must satisfy {2 * RISER_WIDTH} < low <= high [m], got {segment_length!r}")
        max_step = abs(_real(max_step, "max_step"))
        max_slope = abs(_real(max_slope, "max_slope"))
        max_level = _real(max_level, "max_level", positive=True)
        edges, levels, slopes = [start], [0.0], [0.0]
        x, h = start, 0.0
        end = start + length
        while x < end:
            seg = float(rng.uniform(lo, hi))
            step = kind == "steps" or (kind == "mixed" and rng.uniform() < 0.5)
            if step:
                level = h + float(rng.uniform(-max_step, max_step))
                if abs(level) > max_level:
                    level = math.copysign(2 * max_level - abs(level), level)
                slope = 0.0
            else:
                level = h
                slope = float(rng.uniform(-max_slope, max_slope))
                if abs(level + slope * seg) > max_level:
                    slope = -slope
            levels.append(level)
            slopes.append(slope)
            x += seg
            h = level + slope * seg
            edges.append(x)
        levels.append(h)
        slopes.append(0.0)
        return cls(tuple(edges), tuple(levels), (False,) * len(levels), tuple(slopes))

    def to_dict(self) -> dict:
        """The profile as JSON-serializable lists (``edges``, ``levels``, ``gaps``, ``slopes``);
        [`from_dict`][from_dict] rebuilds it."""
        return {"edges": list(self.edges), "levels": list(self.levels), "gaps": list(self.gaps),
                "slopes": list(self.slopes)}

    @classmethod
    def from_dict(cls, data: dict, name: str = "terrain") -> Terrain:
        """The [`Terrain`][Terrain] of [`to_dict`][to_dict]'s dict (``slopes`` optional); errors name ``name``."""
        if not isinstance(data, dict):
            raise TypeError(f"{name} must be a dict, got {type(data).__name__}")
        extra = sorted(set(data) - {"edges", "levels", "gaps", "slopes"})
        if extra or not {"edges", "levels", "gaps"} <= set(data):
            raise ValueError(f"{name} needs the keys 'edges', 'levels', 'gaps' (and optionally 'slopes'), "
                             f"got {sorted(data)}")
        slopes = data.get("slopes")
        return cls(tuple(data["edges"]), tuple(data["levels"]), tuple(data["gaps"]),
                   None if slopes is None else tuple(slopes))

    def raised(self, dz: float) -> Terrain:
        """The same profile ``dz`` [m] higher (lower if ``dz < 0``): every level, gap floors included."""
        dz = _real(dz, "dz")
        return Terrain(self.edges, tuple(v + dz for v in self.levels), self.gaps, self.slopes)

    # ------------------------------------------------------------------ queries
    @property
    def is_flat(self) -> bool:
        """True when ``h(x) = 0`` everywhere (no gap)."""
        return self.uniform_height == 0.0

    @property
    def uniform_height(self) -> float | None:
        """The ground's height [m] when it is one level everywhere (no gap, no slope, every segment at the same
        height; e.g. a flat ground [`raised`][raised]), else None."""
        if any(self.gaps) or any(v != 0.0 for v in self.slopes) or any(v != self.levels[0] for v in self.levels):
            return None
        return self.levels[0]

    def _segments(self, xs: np.ndarray) -> np.ndarray:
        return np.searchsorted(self._edges, xs, side="right")

    def height(self, x: float) -> float:
        """Ground height ``h(x)`` [m] at ``x`` [m] (a gap: its floor for the planner)."""
        x = _real(x, "x")
        i = int(np.searchsorted(self._edges, x, side="right"))
        if self._slopes[i] == 0.0:
            return float(self._levels[i])
        return float(self._levels[i] + self._slopes[i] * (x - self._anchors[i]))

    def heights(self, xs) -> np.ndarray:
        """Vectorised [`height`][height]: ``xs`` any shape [m] -> heights of the same shape [m]."""
        xs = np.asarray(xs, dtype=np.float64)
        if not np.all(np.isfinite(xs)):
            raise ValueError("xs must be finite [m]")
        seg = self._segments(xs)
        if not self._slopes.any():
            return self._levels[seg]
        return self._levels[seg] + self._slopes[seg] * (xs - self._anchors[seg])

    # ------------------------------------------------------------------ the simulated surface
    def surface_vertices(self, riser: float = RISER_WIDTH) -> tuple[np.ndarray, np.ndarray]:
        """The continuous piecewise-linear surface the contact simulation uses (see the module docstring):
        vertices ``(xs (n,), zs (n,))`` [m], ``xs`` strictly increasing, level beyond both ends. A jump of ``h`` at an
        edge ``e`` is a ramp over ``[e - riser, e]``; every segment must be longer than ``riser`` (ValueError naming
        ``edges`` otherwise)."""
        riser = _real(riser, "riser", positive=True)
        if riser == RISER_WIDTH and self._surface is not None:
            return self._surface
        e = self.edges
        if any(b - a <= riser for a, b in zip(e, e[1:])):
            raise ValueError(f"edges must be more than riser = {riser} m apart for the simulated surface, "
                             f"got {list(e)}")

        def line(i, x):
            return self.levels[i] + self.slopes[i] * (x - float(self._anchors[i]))

        left = (e[0] if e else 0.0) - SURFACE_EXTENT
        right = (e[-1] if e else 0.0) + SURFACE_EXTENT
        xs, zs = [left], [line(0, left)]
        for j, edge in enumerate(e):
            before, after = line(j, edge), line(j + 1, edge)
            if abs(before - after) > 1e-12 * max(1.0, abs(before)):  # a jump (not the float error of a slope)
                xs.append(edge - riser)
                zs.append(line(j, edge - riser))
            xs.append(edge)
            zs.append(after)
        xs.append(right)
        zs.append(line(len(e), right))
        out = (np.array(xs, dtype=np.float64), np.array(zs, dtype=np.float64))
        out[0].flags.writeable = out[1].flags.writeable = False
        if riser == RISER_WIDTH:
            object.__setattr__(self, "_surface", out)
        return out

    def _surface_pieces(self, xs):
        """``(xs, vx, vz, j, s)``: ``xs`` as finite floats, the surface's vertices, the index ``j`` of the piece
        ``[x_j, x_j+1)`` under each x (the end pieces beyond the ends) and that piece's slope ``s``."""
        xs = np.asarray(xs, dtype=np.float64)
        if not np.all(np.isfinite(xs)):
            raise ValueError("xs must be finite [m]")
        vx, vz = self.surface_vertices()
        j = np.clip(np.searchsorted(vx, xs, side="right") - 1, 0, len(vx) - 2)
        return xs, vx, vz, j, (vz[j + 1] - vz[j]) / (vx[j + 1] - vx[j])

    def surface_heights(self, xs) -> np.ndarray:
        """Height [m] of the simulated surface ([`surface_vertices`][surface_vertices]) at ``xs`` (any shape) [m], with
        the contact kernel's arithmetic (``z_j + s (x - x_j)`` on the piece ``[x_j, x_j+1)``, level beyond the ends)."""
        xs, vx, vz, j, s = self._surface_pieces(xs)
        h = vz[j] + s * (xs - vx[j])
        return np.where(xs < vx[0], vz[0], np.where(xs >= vx[-1], vz[-1], h))

    def surface_normals(self, xs) -> np.ndarray:
        """Unit outward normals ``(..., 2)`` ``(n_x, n_z)`` of the simulated surface at ``xs`` (any shape) [m]:
        ``(-s, 1) / sqrt(1 + s^2)`` with ``s`` the slope of the piece under x (a point on a vertex belongs to the
        piece on its right)."""
        xs, vx, _, _, s = self._surface_pieces(xs)
        s = np.where((xs < vx[0]) | (xs >= vx[-1]), 0.0, s)
        inv = 1.0 / np.sqrt(1.0 + s * s)
        return np.stack([-s * inv, inv], axis=-1)

    def support_heights(self, xs) -> np.ndarray:
        """The ground [m] under ``xs`` (any shape) [m] that a trunk is measured from: [`heights`][heights] with each gap
        bridged at the level of its near (left) edge (the right one for a leading gap)."""
        xs = np.asarray(xs, dtype=np.float64)
        h = self.heights(xs)
        if not any(self.gaps):
            return h
        seg = self._segments(xs)
        return np.where(self._gaps[seg], self._bridged[seg], h)

    def support_height(self, x: float) -> float:
        """[`support_heights`][support_heights] of one finite ``x`` [m] (a float, in plain Python arithmetic: the
        envs' per-step path)."""
        if not math.isfinite(x):
            raise ValueError(f"x must be finite [m], got {x!r}")
        i = bisect.bisect_right(self.edges, x)
        if self.gaps[i]:
            return self._bridged_t[i]
        slope = self.slopes[i]
        if slope == 0.0:
            return self.levels[i]
        return self.levels[i] + slope * (x - self._anchors_t[i])

    def gap_at(self, x: float) -> bool:
        """[`over_gap`][over_gap] of one finite ``x`` [m] (a float)."""
        if not math.isfinite(x):
            raise ValueError(f"x must be finite [m], got {x!r}")
        return self.gaps[bisect.bisect_right(self.edges, x)]

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
            elif self.slopes[i] != 0.0:
                parts.append(f"slope {self.slopes[i]:+.3f} from {lvl:+.2f} m for x in [{bounds[i]:.2f}, "
                             f"{bounds[i + 1]:.2f})")
            elif lvl != 0.0:
                parts.append(f"ground at {lvl:+.2f} m for x in [{bounds[i]:.2f}, {bounds[i + 1]:.2f})")
        return "; ".join(parts)


FLAT = Terrain()
"""The flat ground ``h = 0``."""


def check_terrain(terrain, name: str = "terrain") -> Terrain | None:
    """``terrain`` if it is a [`Terrain`][Terrain] or None; TypeError naming ``name`` otherwise."""
    if terrain is not None and not isinstance(terrain, Terrain):
        raise TypeError(f"{name} must be a Terrain or None, got {type(terrain).__name__}")
    return terrain


__all__ = ["GAP_DEPTH", "FLAT", "RISER_WIDTH", "SAMPLE_KINDS", "SURFACE_EXTENT", "Terrain", "check_terrain"]

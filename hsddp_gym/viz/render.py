"""Off-screen drawing of the planar Mini Cheetah (no display needed) and GIF / MP4 export.

[`render_state`][render_state] turns a state ``x (14,)`` into an RGB image ``(height, width, 3) uint8`` with Pillow's
``ImageDraw``: ground with distance ticks every 0.1 m, trunk, legs, feet (filled when in contact) and
optional ground-reaction-force arrows. The camera follows the trunk horizontally. The env's
``render()`` and the CLI (planned trajectories) both use it. [`save_gif`][save_gif] writes frames atomically.

Pillow is an optional dependency (``pip install hsddp_gym[viz]``); it is imported on first use.
"""

from __future__ import annotations

import math
import os

import numpy as np

from hsddp_gym.core.conventions import FEET, NGRF, NQ, NX
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.util.io import atomic_path
from hsddp_gym.util.validation import check_int, check_positive, check_vector

BACKGROUND = (245, 245, 240)
GROUND = (90, 80, 70)
TRUNK = (40, 70, 140)
LEG_COLORS = ((200, 80, 40), (60, 140, 70))
"""Front leg, back leg."""
GRF_COLOR = (200, 30, 160)
TEXT = (30, 30, 30)

_ROBOTS: dict = {}


def _pil():
    try:
        from PIL import Image, ImageDraw
    except ImportError as exc:  # pragma: no cover - pillow is installed with the viz/data extras
        raise ImportError("drawing needs Pillow: pip install 'hsddp_gym[viz]' (or pip install pillow)") from exc
    return Image, ImageDraw


def _robot(robot: CheetahModel | None) -> CheetahModel:
    if robot is not None:
        if not isinstance(robot, CheetahModel):
            raise TypeError(f"robot must be a CheetahModel, got {type(robot).__name__}")
        return robot
    if "default" not in _ROBOTS:
        _ROBOTS["default"] = CheetahModel()
    return _ROBOTS["default"]


def render_state(x: np.ndarray, *, robot: CheetahModel | None = None, width: int = 480, height: int = 320,
                 pixels_per_meter: float | None = None, grf: np.ndarray | None = None, contact=None,
                 grf_scale: float = 0.002, camera_x: float | None = None, ground_row: float = 0.8,
                 text: str | None = None, terrain=None) -> np.ndarray:
    """Draw the robot in state ``x``.

    Args:
        x: state (14,) (only ``q = x[:7]`` is drawn; a (7,) configuration is accepted too).
        robot: the model (default: the paper's robot).
        width: image width [px].
        height: image height [px].
        pixels_per_meter: drawing scale (default: fit a 1.3 m wide, 0.6 m tall window).
        grf: optional ground forces (4,) ``[f_front_x, f_front_z, f_back_x, f_back_z]`` [N], drawn as arrows
            from each foot, ``grf_scale`` meters per newton.
        contact: optional flags (2,) ``[front, back]``; a foot in contact is drawn filled. Default: feet at
            most 1 mm above the ground.
        camera_x: world x at the image centre (default: the trunk x).
        ground_row: the ground line at this fraction of the height, in (0, 1].
        text: optional caption drawn in the top-left corner.
        terrain: the ground's profile (a [`Terrain`][hsddp_gym.core.terrain.Terrain], None: flat ``z = 0``): its
            simulated surface ([`surface_vertices`][hsddp_gym.core.terrain.Terrain.surface_vertices]) is drawn filled
            below, with the distance ticks on it; a foot's default contact flag measures from it.
    Returns:
        ``(height, width, 3)`` uint8 RGB image.
    """
    x = np.asarray(x, dtype=np.float64)
    q = check_vector(x[:NQ] if x.shape == (NX,) else x, NQ, "x (state (14,) or configuration (7,))")
    width = check_int(width, "width", minimum=16)
    height = check_int(height, "height", minimum=16)
    ppm = min(width / 1.3, height / 0.6) if pixels_per_meter is None else check_positive(pixels_per_meter,
                                                                                           "pixels_per_meter")
    rob = _robot(robot)
    if terrain is not None:
        from hsddp_gym.core.terrain import check_terrain

        terrain = check_terrain(terrain)
    pts = rob.link_points(q)  # (2, 4, 2): per foot [hip, knee, foot, trunk origin]
    cx = float(q[0]) if camera_x is None else float(camera_x)
    gz = float(np.clip(ground_row, 0.05, 1.0)) * height

    def px(p):
        return (width / 2.0 + (p[0] - cx) * ppm, gz - p[1] * ppm)

    Image, ImageDraw = _pil()
    img = Image.new("RGB", (width, height), BACKGROUND)
    draw = ImageDraw.Draw(img)
    # ground and distance ticks (every 0.1 m, longer every 1 m)
    half = width / (2.0 * ppm)
    if terrain is None:
        draw.rectangle([0, gz, width, height], fill=(225, 220, 205))
        draw.line([(0, gz), (width, gz)], fill=GROUND, width=2)
    else:  # the surface's polyline over the view, filled down to the image's bottom
        vx, vz = terrain.surface_vertices()
        lo, hi = cx - half - 0.1, cx + half + 0.1
        inside = vx[(vx > lo) & (vx < hi)]
        xs = np.concatenate([[lo], inside, [hi]])
        line = [px((xv, zv)) for xv, zv in zip(xs, terrain.surface_heights(xs))]
        draw.polygon(line + [(line[-1][0], height + 1), (line[0][0], height + 1)], fill=(225, 220, 205))
        draw.line(line, fill=GROUND, width=2)
    for i in range(int(np.floor((cx - half) * 10)), int(np.ceil((cx + half) * 10)) + 1):
        u = width / 2.0 + (i / 10.0 - cx) * ppm
        g = gz if terrain is None else px((i / 10.0, float(terrain.surface_heights(i / 10.0))))[1]
        draw.line([(u, g), (u, g + (10 if i % 10 == 0 else 5))], fill=GROUND, width=1)
    lw = max(2, int(round(0.02 * ppm)))
    # trunk between the hips, and the trunk origin
    hips = [px(pts[f, 0]) for f in FEET]
    draw.line([hips[1], hips[0]], fill=TRUNK, width=max(lw + 4, int(round(0.05 * ppm))))
    o = px(pts[0, 3])
    r0 = max(2, lw // 2)
    draw.ellipse([o[0] - r0, o[1] - r0, o[0] + r0, o[1] + r0], fill=(250, 250, 250))
    if contact is None:
        ground = (0.0, 0.0) if terrain is None else terrain.surface_heights(pts[:, 2, 0])
        on_ground = [pts[f, 2, 1] - ground[f] <= 1e-3 for f in FEET]
    else:
        on_ground = [bool(contact[f]) for f in FEET]
    rf = max(3, int(round(0.015 * ppm)))
    for f in FEET:
        hip, knee, foot = px(pts[f, 0]), px(pts[f, 1]), px(pts[f, 2])
        draw.line([hip, knee, foot], fill=LEG_COLORS[f], width=lw, joint="curve")
        draw.ellipse([knee[0] - r0, knee[1] - r0, knee[0] + r0, knee[1] + r0], fill=LEG_COLORS[f])
        box = [foot[0] - rf, foot[1] - rf, foot[0] + rf, foot[1] + rf]
        if on_ground[f]:
            draw.ellipse(box, fill=(20, 20, 20))
        else:
            draw.ellipse(box, outline=(20, 20, 20), width=2)
    if grf is not None:
        g = check_vector(grf, NGRF, "grf")
        s = check_positive(grf_scale, "grf_scale")
        for f in FEET:
            fx, fz = g[2 * f], g[2 * f + 1]
            if fx == 0.0 and fz == 0.0:
                continue
            a = pts[f, 2]
            b = a + s * np.array([fx, fz])
            _arrow(draw, px(a), px(b), GRF_COLOR, max(1, lw // 2))
    if text:
        draw.text((6, 4), str(text), fill=TEXT)
    return np.asarray(img, dtype=np.uint8)


def _arrow(draw, a, b, color, width) -> None:
    draw.line([a, b], fill=color, width=width)
    d = np.array(b) - np.array(a)
    n = float(np.hypot(*d))
    if n < 1e-9:
        return
    d /= n
    head = min(10.0, 0.4 * n)
    side = np.array([-d[1], d[0]])
    p1 = np.array(b) - head * d + 0.5 * head * side
    p2 = np.array(b) - head * d - 0.5 * head * side
    draw.polygon([tuple(b), tuple(p1), tuple(p2)], fill=color)


def render_trajectory(X: np.ndarray, *, every: int = 1, robot: CheetahModel | None = None, **kwargs) -> list:
    """Draw every ``every``-th state of ``X (N, 14)``; keyword arguments go to [`render_state`][render_state].

    Returns:
        A list of ``(height, width, 3)`` uint8 frames.
    """
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] not in (NQ, NX):
        raise ValueError(f"X must have shape (N, {NX}) or (N, {NQ}), got {X.shape}")
    every = check_int(every, "every", minimum=1)
    rob = _robot(robot)
    return [render_state(x, robot=rob, **kwargs) for x in X[::every]]


GIF_MIN_DELAY_MS = 20
"""The shortest frame delay a GIF gets: delays are stored in centiseconds and many viewers (browsers among them)
replace delays of 10 ms or less by 100 ms, so faster frame rates are written by dropping frames."""


def gif_timing(n_frames: int, fps: float, min_delay_ms: float = GIF_MIN_DELAY_MS) -> tuple[int, list[int]]:
    """``(stride, durations_ms)`` that play ``n_frames`` frames of rate ``fps`` in real time as a GIF: every
    ``stride``-th frame is kept (the smallest stride with a delay >= ``min_delay_ms``), and the kept frames'
    delays are whole centiseconds whose running sum follows the frames' real time to within 5 ms (so a
    30-fps clip alternates 30 and 40 ms). ``len(durations_ms) == ceil(n_frames / stride)``; the sum is the
    clip's real duration ``n_frames / fps`` to within one delay (the last frame keeps the minimum delay)."""
    n_frames = check_int(n_frames, "n_frames", minimum=1)
    fps = check_positive(fps, "fps")
    min_delay_ms = check_positive(min_delay_ms, "min_delay_ms")
    period_ms = 1000.0 / fps
    stride = max(1, math.ceil(min_delay_ms / period_ms - 1e-9))
    kept = range(0, n_frames, stride)
    ends = [min(i + stride, n_frames) * period_ms for i in kept]
    cs = [round(e / 10.0) for e in ends]
    durations = [10 * (c - p) for c, p in zip(cs, [0, *cs[:-1]])]
    floor_cs = math.ceil(min_delay_ms / 10.0 - 1e-9)
    durations = [max(d, 10 * floor_cs) for d in durations]  # rounding may shorten one below the floor
    return stride, durations


GIF_COLORS = 8
"""Colours of a GIF's shared palette: the renders are drawings of a few flat colours (ground, trunk, legs, text), and a
palette of 8 shared by all frames writes the docs' GIFs at under half the size of a palette per frame."""


def _shared_palette(imgs: list, Image) -> list:
    """``imgs`` (RGB) in one adaptive palette of [`GIF_COLORS`][GIF_COLORS] colours drawn from all of them, without
    dithering: a GIF of drawings a fraction of the size of one with a palette per frame."""
    step = max(1, len(imgs) // 16)
    sample = imgs[::step]
    w, h = sample[0].size
    strip = Image.new("RGB", (w, h * len(sample)))
    for i, im in enumerate(sample):
        strip.paste(im, (0, i * h))
    palette = strip.quantize(colors=GIF_COLORS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    return [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in imgs]


def save_gif(frames, path: str | os.PathLike, fps: float = 30.0, min_delay_ms: float = GIF_MIN_DELAY_MS) -> str:
    """Write frames to a GIF (Pillow) or, for a ``.mp4`` path, an MP4 (needs ``imageio-ffmpeg``).

    A GIF plays in **real time**: frames faster than ``min_delay_ms`` (default 20 ms, the shortest delay GIF
    viewers honour) are dropped, e.g. the env's 5-ms frames are written every 4th at 20 ms each (see
    [`gif_timing`][gif_timing]). An MP4 keeps every frame at ``fps``.

    The file is written to a temporary name in the same directory and then renamed over ``path``, so a
    reader never sees a half-written file.

    Args:
        frames: sequence of ``(H, W, 3)`` uint8 images of one size (at least one).
        path: output file ending in ``.gif`` or ``.mp4``.
        fps: frames per second of ``frames`` (> 0).
        min_delay_ms: GIF only: the shortest frame delay written [ms].
    Returns:
        The path written, as a string.
    """
    fps = check_positive(fps, "fps")
    min_delay_ms = check_positive(min_delay_ms, "min_delay_ms")
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".gif", ".mp4"):
        raise ValueError(f"path must end in .gif or .mp4, got {path!r}")
    frames = [np.asarray(f) for f in frames]
    if not frames:
        raise ValueError("frames must hold at least one image")
    shape = frames[0].shape
    for i, f in enumerate(frames):
        if f.ndim != 3 or f.shape[2] != 3 or f.dtype != np.uint8:
            raise ValueError(f"frames[{i}] must be an (H, W, 3) uint8 image, got shape {f.shape} dtype {f.dtype}")
        if f.shape != shape:
            raise ValueError(f"all frames must have the same shape {shape}, frames[{i}] has {f.shape}")
    with atomic_path(path, suffix=ext) as tmp:
        if ext == ".gif":
            Image, _ = _pil()
            stride, durations = gif_timing(len(frames), fps, min_delay_ms)
            imgs = _shared_palette([Image.fromarray(f) for f in frames[::stride]], Image)
            imgs[0].save(tmp, format="GIF", save_all=True, append_images=imgs[1:],
                         duration=durations if len(imgs) > 1 else durations[0], loop=0, optimize=True)
        else:
            try:
                import imageio.v2 as imageio
                import imageio_ffmpeg  # noqa: F401
            except ImportError as exc:
                raise ImportError("writing .mp4 needs imageio and imageio-ffmpeg "
                                  "(pip install imageio imageio-ffmpeg); use a .gif path instead") from exc
            imageio.mimsave(tmp, frames, fps=fps, format="FFMPEG")
    return path

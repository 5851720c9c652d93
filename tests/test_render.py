"""Off-screen drawing (hsddp_gym/render.py) and the env's render modes."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.viz.render import render_state, render_trajectory, save_gif

PIL = pytest.importorskip("PIL")


def test_render_state_shape_dtype_and_content():
    x = paper_initial_state()
    img = render_state(x, width=200, height=120)
    assert img.shape == (120, 200, 3) and img.dtype == np.uint8
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 4  # ground, trunk, legs, feet, background
    moved = x.copy()
    moved[3] += 0.5  # swing the front thigh
    assert not np.array_equal(img, render_state(moved, width=200, height=120))
    # a configuration (7,) draws the same picture as the state
    np.testing.assert_array_equal(img, render_state(x[:7], width=200, height=120))


def test_grf_arrows_and_contact_markers_are_drawn():
    x = paper_initial_state()
    plain = render_state(x, contact=[False, False])
    with_grf = render_state(x, contact=[False, False], grf=[0.0, 0.0, 30.0, 150.0])
    with_contact = render_state(x, contact=[False, True])
    diff = np.any(plain != with_grf, axis=2)
    assert diff.sum() > 50
    assert not np.array_equal(plain, with_contact)


def test_render_trajectory_and_bad_inputs():
    X = np.repeat(paper_initial_state()[None], 6, axis=0)
    frames = render_trajectory(X, every=2, width=64, height=48)
    assert len(frames) == 3 and frames[0].shape == (48, 64, 3)
    with pytest.raises(ValueError, match="x"):
        render_state(np.zeros(5))
    with pytest.raises(ValueError, match="finite"):
        render_state(np.full(14, np.nan))
    with pytest.raises(ValueError, match="width"):
        render_state(paper_initial_state(), width=3)
    with pytest.raises(ValueError, match="X must have shape"):
        render_trajectory(np.zeros((3, 5)))


def test_save_gif_is_atomic_and_readable(tmp_path):
    from PIL import Image

    frames = [render_state(paper_initial_state(), width=80, height=60) for _ in range(3)]
    frames[1] = frames[1].copy()
    frames[1][:10] = 0
    path = save_gif(frames, tmp_path / "robot.gif", fps=10)
    assert os.path.exists(path)
    assert sorted(os.listdir(tmp_path)) == ["robot.gif"]  # no temporary file left behind
    with Image.open(path) as im:
        assert im.size == (80, 60) and im.n_frames == 3
    # overwrite in place
    save_gif(frames[:2], path, fps=10)
    with Image.open(path) as im:
        assert im.n_frames == 2
    with pytest.raises(ValueError, match="gif or .mp4"):
        save_gif(frames, tmp_path / "robot.png")
    with pytest.raises(ValueError, match="at least one"):
        save_gif([], tmp_path / "empty.gif")
    with pytest.raises(ValueError, match="same shape"):
        save_gif([frames[0], frames[0][:30]], tmp_path / "mixed.gif")
    with pytest.raises(ValueError, match="uint8"):
        save_gif([frames[0].astype(float)], tmp_path / "float.gif")
    with pytest.raises(ValueError, match="fps"):
        save_gif(frames, tmp_path / "fps.gif", fps=0)
    assert sorted(os.listdir(tmp_path)) == ["robot.gif"]


def test_save_mp4_needs_imageio_ffmpeg(tmp_path):
    frames = [render_state(paper_initial_state(), width=64, height=48)] * 2
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="imageio-ffmpeg"):
            save_gif(frames, tmp_path / "robot.mp4", fps=10)
        assert os.listdir(tmp_path) == []
    else:  # pragma: no cover - only where imageio-ffmpeg is installed
        assert os.path.getsize(save_gif(frames, tmp_path / "robot.mp4", fps=10)) > 0


def test_env_rgb_array_and_headless_human_rendering():
    env = BoundingEnv(render_mode="rgb_array", width=160, height=100)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (100, 160, 3) and frame.dtype == np.uint8
    env.step(np.zeros(4))
    assert not np.array_equal(frame, env.render())
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert BoundingEnv().render() is None  # no render mode: a warning, no image
    human = BoundingEnv(render_mode="human", width=64, height=48)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        human.reset(seed=0)
        human.step(np.zeros(4))
        assert human.render() is None
    human.close()
    env.close()


def test_push_gif_shows_both_policies_side_by_side(tmp_path, experiment):
    out = tmp_path / "push.gif"
    push_gif = experiment("push_gif")
    assert push_gif.main(["--out", str(out), "--after", "0.1", "--before", "0.05", "--stride", "5"]) == 0
    with PIL.Image.open(out) as gif:
        assert gif.n_frames == 7 and gif.size == (720, 240)
    with pytest.raises(SystemExit):
        push_gif.main(["--out", str(out), "--stride", "0"])


def _distinct_frames(n, w=40, h=30):
    """``n`` frames that differ (Pillow merges identical consecutive frames)."""
    out = []
    for i in range(n):
        f = np.zeros((h, w, 3), dtype=np.uint8)
        f[:, i % w] = 255
        f[0, 0] = (i * 37) % 256
        out.append(f)
    return out


def _gif_durations(path):
    from PIL import Image

    durations = []
    with Image.open(path) as im:
        for i in range(im.n_frames):
            im.seek(i)
            durations.append(im.info["duration"])
    return durations


@pytest.mark.parametrize("fps, n, stride", [(200, 40, 4), (100, 30, 2), (30, 30, 1), (10, 5, 1)])
def test_gifs_play_in_real_time_with_delays_viewers_honour(tmp_path, fps, n, stride):
    """The env's 5-ms frames used to be written at 10 ms (half speed; and many viewers show <= 10 ms as 100
    ms): now frames are dropped to delays >= 20 ms in whole centiseconds, and the clip lasts its real time."""
    from hsddp_gym.viz.render import gif_timing

    path = save_gif(_distinct_frames(n), tmp_path / "clip.gif", fps=fps)
    durations = _gif_durations(path)
    assert len(durations) == len(range(0, n, stride)) == len(gif_timing(n, fps)[1])
    assert all(d >= 20 and d % 10 == 0 for d in durations)
    real_ms = 1000.0 * n / fps
    assert abs(sum(durations) - real_ms) <= max(10.0, 20.0 - 1000.0 / fps * ((n - 1) % stride + 1)) + 1e-9
    # the running sum follows real time frame by frame (within 5 ms + the last frame's floor)
    ends = np.cumsum(durations)[:-1]
    shown = np.array([min(i + stride, n) * 1000.0 / fps for i in range(0, n, stride)])[:-1]
    assert np.all(np.abs(ends - shown) <= 5.0 + 1e-9)


def test_rollout_video_says_its_playback_speed(tmp_path, capsys):
    import json

    from hsddp_gym import cli

    out = tmp_path / "r"
    assert cli.main(["rollout", "--policy", "heuristic", "--episodes", "1", "--max-episode-steps", "12", "--video",
                     "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    s = json.loads((out / "summary.json").read_text())
    assert s["video_playback"].startswith("real time: every 4th of the 5-ms frames, 20 ms each")
    assert f"writing {out / 'episode0.gif'}" in printed and "real time" in printed
    # 13 frames (the reset and 12 steps): every 4th of them, 0, 4, 8, 12
    assert _gif_durations(out / "episode0.gif") == [20, 20, 20, 20] and s["video_frames"] == 4


def test_a_gif_of_drawings_keeps_their_colours_in_one_small_palette(tmp_path):
    """Frames of a few flat colours come back exactly from the GIF (one shared palette, no dithering)."""
    from PIL import Image

    from hsddp_gym.viz.render import GIF_COLORS, save_gif

    colours = np.array([[245, 243, 238], [40, 70, 160], [200, 80, 40], [60, 140, 60], [0, 0, 0]], dtype=np.uint8)
    rng = np.random.default_rng(0)
    frames = [colours[rng.integers(0, len(colours), size=(24, 32))] for _ in range(6)]
    path = save_gif(frames, tmp_path / "flat.gif", fps=50.0)
    with Image.open(path) as gif:
        for i in range(gif.n_frames):
            gif.seek(i)
            np.testing.assert_array_equal(np.asarray(gif.convert("RGB")), frames[i])
            assert len(gif.convert("RGB").getcolors(GIF_COLORS + 1)) <= GIF_COLORS

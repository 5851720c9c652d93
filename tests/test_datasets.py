"""Demonstration datasets: Minari loading, environment recovery, the infos schema, determinism across worker
counts, refusal to overwrite, atomic writes, and the planner fields recorded from a short MPC run."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym import cli
from hsddp_gym.datasets import (
    DECISION_SCHEMA,
    GAIN_KEY,
    PolicySpec,
    collect_episodes,
    generate_dataset,
    load_minari,
    load_npz,
    minari_root,
    read_metadata,
)

STEPS = 50
EPISODES = 3
REQUIRED_INFOS = {"qpos": (7,), "qvel": (7,), "contact": (2,), "expert_state_nominal": (14,),
                  "expert_action_nominal": (4,), "solver_iterations": (), "solver_converged": (),
                  "max_violation": (), "solve_ms": (), "replanned": ()}


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("data") / "heuristic"
    generate_dataset("heuristic", EPISODES, out, seed=0, workers=1, max_episode_steps=STEPS, progress=False)
    return out


def _leftovers(parent, name):
    return [p.name for p in parent.iterdir() if p.name.startswith(f".{name}.")]


# ------------------------------------------------------------------------------------------ loading
def test_minari_load_lengths_and_metadata(small):
    import minari

    meta = read_metadata(small)
    with minari_root(small / "minari"):
        ds = minari.load_dataset(meta["dataset_id"])
    assert ds.total_episodes == EPISODES
    flat = load_npz(small)
    lengths = np.diff(flat.episode_starts)
    assert ds.total_steps == int(lengths.sum()) == meta["total_steps"]
    for i, ep in enumerate(ds.iterate_episodes()):
        T = len(ep.actions)
        assert T == lengths[i] <= STEPS
        assert ep.observations.shape == (T + 1, 17) and ep.observations.dtype == np.float32
        assert ep.rewards.shape == ep.terminations.shape == ep.truncations.shape == (T,)
        assert bool(ep.terminations[-1]) or bool(ep.truncations[-1])
        e = flat.episode(i)
        np.testing.assert_array_equal(ep.observations, e["observations"])
        np.testing.assert_array_equal(ep.actions, e["actions"])
        np.testing.assert_allclose(ep.rewards, e["rewards"])
    md = ds.storage.metadata
    assert md["ref_min_score"] == pytest.approx(meta["ref_min_score"])
    assert md["ref_max_score"] == pytest.approx(np.mean(meta["episode_returns"]))
    assert md["hsddp_gym"]["policy"]["name"] == "heuristic"
    assert meta["episode_seeds"] == [0, 1, 2] and meta["max_episode_steps"] == STEPS
    assert meta["env_spec"]["id"] == "hsddp_gym/Bounding-v0"


def test_infos_schema_fixed_at_every_row(small):
    ds = load_minari(small)
    for ep in ds.iterate_episodes():
        T = len(ep.actions)
        for key, shape in REQUIRED_INFOS.items():
            assert key in ep.infos, key
            assert ep.infos[key].shape == (T + 1, *shape), (key, ep.infos[key].shape)
        assert set(ep.infos) >= set(DECISION_SCHEMA)
        # row t describes observation t: the stored state reproduces the observation
        np.testing.assert_allclose(ep.infos["qpos"][:, 1:], ep.observations[:, :6], atol=1e-5)
        np.testing.assert_allclose(ep.infos["qvel"], ep.observations[:, 6:13], atol=1e-4)
        # the heuristic has no planner: zeros
        assert not ep.infos["replanned"].any() and not ep.infos["expert_tracking"].any()
        assert np.all(ep.infos["expert_state_nominal"] == 0.0)


def test_recover_environment_in_a_fresh_process(small):
    meta = read_metadata(small)
    code = ("import minari\n"
            f"ds = minari.load_dataset({meta['dataset_id']!r})\n"
            "env = ds.recover_environment()\n"
            "obs, info = env.reset(seed=0)\n"
            "print(env.spec.id, env.spec.max_episode_steps, obs.shape[0], ds.total_episodes)\n")
    env = {**os.environ, "MINARI_DATASETS_PATH": str(small / "minari")}
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120,
                         cwd=str(small))
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["hsddp_gym/Bounding-v0", str(STEPS), "17", str(EPISODES)]


def test_same_data_whatever_the_number_of_workers(small, tmp_path):
    out = tmp_path / "w2"
    generate_dataset("heuristic", EPISODES, out, seed=0, workers=2, max_episode_steps=STEPS, progress=False)
    a, b = load_npz(small), load_npz(out)
    for name in ("observations", "actions", "rewards", "terminations", "truncations", "episode_starts",
                 "episode_seeds"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert set(a.infos) == set(b.infos)
    for k in a.infos:
        np.testing.assert_array_equal(a.infos[k], b.infos[k], err_msg=k)


def test_random_policy_episodes_do_not_depend_on_order():
    eps = collect_episodes(PolicySpec("random"), 2, seed=5, max_episode_steps=20, progress=False)
    again = collect_episodes(PolicySpec("random"), 1, seed=6, max_episode_steps=20, progress=False)
    np.testing.assert_array_equal(eps[1].actions, again[0].actions)


# ------------------------------------------------------------------------------------------ safety
def test_refuses_to_overwrite_without_the_flag(small, tmp_path, capsys):
    before = (small / "episodes.npz").read_bytes()
    with pytest.raises(FileExistsError, match="overwrite"):
        generate_dataset("heuristic", 1, small, max_episode_steps=5, progress=False)
    rc = cli.main(["dataset", "--policy", "heuristic", "--episodes", "1", "--out", str(small),
                   "--max-episode-steps", "5", "--quiet"])
    assert rc == 2 and "--overwrite" in capsys.readouterr().err
    assert (small / "episodes.npz").read_bytes() == before
    # with the flag the dataset is replaced
    out = tmp_path / "replace"
    generate_dataset("heuristic", 2, out, max_episode_steps=5, progress=False)
    rc = cli.main(["dataset", "--policy", "heuristic", "--episodes", "1", "--out", str(out),
                   "--max-episode-steps", "5", "--quiet", "--overwrite"])
    assert rc == 0 and load_minari(out).total_episodes == 1 and read_metadata(out)["episodes"] == 1
    assert _leftovers(tmp_path, "replace") == []


class _Exploding:
    """A policy that raises after a few steps (a crash in the middle of generation)."""

    def __init__(self, after: int) -> None:
        self.after, self.n = after, 0

    def reset(self) -> None:
        self.n = 0

    def __call__(self, obs):
        self.n += 1
        if self.n > self.after:
            raise RuntimeError("boom")
        return np.zeros(4, dtype=np.float32)


def exploding_factory(env, seed):
    return _Exploding(after=3 if seed == 1 else 10_000), None


@pytest.mark.parametrize("workers", [1, 2])
def test_failure_leaves_no_dataset(tmp_path, workers):
    out = tmp_path / "broken"
    with pytest.raises(RuntimeError, match="boom"):
        generate_dataset(exploding_factory, 3, out, workers=workers, max_episode_steps=10, progress=False,
                         policy_name="exploding")
    assert not out.exists()
    assert _leftovers(tmp_path, "broken") == []


def test_failure_with_overwrite_keeps_the_old_dataset(small, tmp_path):
    out = tmp_path / "keep"
    generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False)
    before = (out / "episodes.npz").read_bytes()
    with pytest.raises(RuntimeError, match="boom"):
        generate_dataset(exploding_factory, 2, out, overwrite=True, max_episode_steps=10, progress=False,
                         policy_name="exploding")
    assert (out / "episodes.npz").read_bytes() == before
    assert _leftovers(tmp_path, "keep") == []


# ------------------------------------------------------------------------------------------ planner fields
def test_mpc_fields_and_feedback_law(tmp_path):
    out = tmp_path / "mpc"
    res = generate_dataset("mpc", 1, out, seed=0, max_episode_steps=10, include_gains=True, progress=False)
    meta = res.metadata
    assert meta["policy"]["name"] == "mpc" and "replan_period" in meta["policy"]["options"]
    ep = load_minari(out)[0]
    inf = ep.infos
    T = len(ep.actions)
    period = round(meta["policy"]["options"]["replan_period"] / meta["control_dt"])
    expected = np.zeros(T + 1, dtype=bool)
    expected[:T:period] = True
    np.testing.assert_array_equal(inf["replanned"], expected)
    assert inf["solver_iterations"][0] >= 1 and inf["solve_ms"][0] > 0 and inf["solver_converged"].dtype == bool
    assert inf["expert_tracking"][:T].all()
    assert inf[GAIN_KEY].shape == (T + 1, 4, 14)
    # the stored nominal and gains reproduce the applied actions: a = clip(u_bar + K (x - x_bar))
    x = np.concatenate([inf["qpos"], inf["qvel"]], axis=1)[:T]
    u = inf["expert_action_nominal"][:T] + np.einsum("tij,tj->ti", inf[GAIN_KEY][:T],
                                                     x - inf["expert_state_nominal"][:T])
    np.testing.assert_allclose(np.clip(u, -1, 1), ep.actions, atol=1e-4)
    assert json.loads((out / "metadata.json").read_text())["infos_schema"][GAIN_KEY][0] == [4, 14]


def test_action_noise_executes_noisy_actions_and_stores_clean_labels(tmp_path):
    import json

    from hsddp_gym.datasets import load_npz

    out = tmp_path / "dart"
    generate_dataset("heuristic", 2, out, seed=5, max_episode_steps=25, progress=False, action_noise=0.05)
    d = load_npz(out)
    e = d.episode(0)
    label = e["infos"]["expert_action"]
    assert label.shape == (len(e["actions"]) + 1, 4) and label.dtype == np.float32
    diff = e["actions"] - label[:-1]
    assert 0.02 < diff.std() < 0.08 and np.all(np.abs(e["actions"]) <= 1)
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["action_noise"] == 0.05
    again = tmp_path / "again"
    generate_dataset("heuristic", 2, again, seed=5, max_episode_steps=25, progress=False, action_noise=0.05,
                     workers=2)
    np.testing.assert_array_equal(load_npz(again).actions, d.actions)  # seeded by the episode seed
    with pytest.raises(ValueError):
        generate_dataset("heuristic", 1, tmp_path / "bad", action_noise=-0.1, progress=False)

"""Demonstration datasets: Minari loading, environment recovery, the infos schema, determinism across worker
counts, refusal to overwrite, atomic writes, resuming or refusing after an interrupted run, reference scores,
and the planner fields recorded from a short MPC run."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym import cli
from hsddp_gym.datasets.collection import collect_episodes
from hsddp_gym.datasets.generation import generate_dataset, partial_dir
from hsddp_gym.datasets.recording import DECISION_SCHEMA, GAIN_KEY, NONDETERMINISTIC_INFOS
from hsddp_gym.datasets.storage import load_minari, load_npz, minari_root, read_metadata
from hsddp_gym.rollout.policies import PolicySpec

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


def test_recover_environment_in_a_fresh_process(small, tmp_path):
    meta = read_metadata(small)
    fast = tmp_path / "fast"  # recorded with env kwargs: they must come back too
    generate_dataset("heuristic", 1, fast, max_episode_steps=5, env_kwargs={"target_speed": 1.3}, progress=False,
                     dataset_id="hsddp_gym/bounding/fast-v0")
    code = ("import os, minari\n"  # no hsddp_gym import: the stored spec's entry point builds the env
            f"os.environ['MINARI_DATASETS_PATH'] = {str(small / 'minari')!r}\n"
            f"ds = minari.load_dataset({meta['dataset_id']!r})\n"
            "env = ds.recover_environment()\n"
            "obs, info = env.reset(seed=0)\n"
            "print(env.spec.id, env.spec.max_episode_steps, obs.shape[0], ds.total_episodes)\n"
            f"os.environ['MINARI_DATASETS_PATH'] = {str(fast / 'minari')!r}\n"
            "env = minari.load_dataset('hsddp_gym/bounding/fast-v0').recover_environment()\n"
            "print(env.unwrapped.target_speed, env.spec.max_episode_steps)\n")
    res = subprocess.run([sys.executable, "-c", code], env=dict(os.environ), capture_output=True, text=True,
                         timeout=120, cwd=str(small))
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["hsddp_gym/Bounding-v0", str(STEPS), "17", str(EPISODES), "1.3", "5"]


def test_same_data_whatever_the_number_of_workers(small, tmp_path, tools):
    out = tmp_path / "w2"
    generate_dataset("heuristic", EPISODES, out, seed=0, workers=2, max_episode_steps=STEPS, progress=False)
    tools.assert_same_datasets(small, out)


def test_mpc_data_do_not_depend_on_the_number_of_workers(tmp_path):
    a, b = tmp_path / "w1", tmp_path / "w2"
    generate_dataset("mpc", 2, a, seed=3, workers=1, max_episode_steps=30, progress=False)
    generate_dataset("mpc", 2, b, seed=3, workers=2, max_episode_steps=30, progress=False)
    a, b = load_npz(a), load_npz(b)
    np.testing.assert_array_equal(a.observations, b.observations)
    np.testing.assert_array_equal(a.actions, b.actions)
    assert a.infos["replanned"].any()
    for k in a.infos:
        if k not in NONDETERMINISTIC_INFOS:  # wall-clock solve times
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
    return _Exploding(after=3 if seed == 1 else 10_000)


def flaky_factory(env, seed):
    """Explodes on the episode seeded $HSDDP_TEST_EXPLODE_SEED (read in the worker: spawned workers inherit
    the environment), plays zeros otherwise: an interrupted run, then a rerun with the same settings."""
    bad = os.environ.get("HSDDP_TEST_EXPLODE_SEED")
    return _Exploding(after=3 if bad is not None and int(bad) == seed else 10_000)


@pytest.mark.parametrize("workers", [1, 2])
def test_failure_leaves_no_dataset(tmp_path, workers):
    out = tmp_path / "broken"
    with pytest.raises(RuntimeError, match="boom"):
        generate_dataset(exploding_factory, 3, out, workers=workers, max_episode_steps=10, progress=False,
                         policy_name="exploding")
    assert not out.exists()
    # at most the checkpoints of the finished episodes (to resume from), no temporary dataset directory
    partial = partial_dir(out)
    if workers == 1:  # episode 0 finished before episode 1 failed
        assert _leftovers(tmp_path, "broken") == [".broken.partial"]
        assert sorted(p.name for p in partial.glob("episode-*.npz")) == ["episode-000000.npz"]
        assert (partial / "settings.json").exists()
    else:  # the failure may arrive first: then there is nothing to resume and nothing is left
        assert _leftovers(tmp_path, "broken") in ([], [".broken.partial"])
        assert not (partial / "episode-000001.npz").exists()


@pytest.mark.parametrize("workers", [1, 2])
def test_interrupted_run_resumes_with_the_same_data(tmp_path, monkeypatch, workers):
    out, ref = tmp_path / "resumed", tmp_path / "reference"
    kw = dict(max_episode_steps=12, progress=False, policy_name="flaky", seed=4, workers=workers)
    monkeypatch.setenv("HSDDP_TEST_EXPLODE_SEED", "6")  # episode 2 of 4 fails
    with pytest.raises(RuntimeError, match="boom"):
        generate_dataset(flaky_factory, 4, out, **kw)
    done = sorted(p.name for p in partial_dir(out).glob("episode-*.npz"))
    assert "episode-000002.npz" not in done and (workers == 2 or done == ["episode-000000.npz", "episode-000001.npz"])
    monkeypatch.delenv("HSDDP_TEST_EXPLODE_SEED")
    res = generate_dataset(flaky_factory, 4, out, **kw)
    assert res.resumed_episodes == len(done) and res.metadata["resumed_episodes"] == len(done)
    generate_dataset(flaky_factory, 4, ref, **kw)
    a, b = load_npz(out), load_npz(ref)
    for name in ("observations", "actions", "rewards", "terminations", "truncations", "episode_seeds"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for k in a.infos:
        np.testing.assert_array_equal(a.infos[k], b.infos[k], err_msg=k)
    assert load_minari(out).total_episodes == 4
    assert _leftovers(tmp_path, "resumed") == [] and _leftovers(tmp_path, "reference") == []


def _interrupt_while_writing(monkeypatch):
    """Make the final write raise KeyboardInterrupt (Ctrl-C after every episode is checkpointed)."""
    import hsddp_gym.datasets.generation as D

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(D, "write_dataset", interrupted)


def test_rerun_resumes_or_refuses_on_the_command_line(tmp_path, monkeypatch, capsys):
    out = tmp_path / "cli"
    argv = ["dataset", "--policy", "heuristic", "--episodes", "3", "--seed", "2", "--out", str(out),
            "--max-episode-steps", "8", "--quiet"]
    with monkeypatch.context() as m:
        _interrupt_while_writing(m)
        assert cli.main(argv) == 130
    err = capsys.readouterr().err
    assert "interrupted" in err and "3 finished episode(s)" in err and "resume" in err
    assert not out.exists() and len(list(partial_dir(out).glob("episode-*.npz"))) == 3
    # other settings: refused, with the differing setting named, and the checkpoints kept
    assert cli.main([*argv[:-3], "--max-episode-steps", "9", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "other settings" in err and "max_episode_steps" in err and "--no-resume" in err
    assert len(list(partial_dir(out).glob("episode-*.npz"))) == 3 and not out.exists()
    # the same settings: resumed
    assert cli.main(argv) == 0
    assert "3 episode(s) resumed" in capsys.readouterr().out
    assert read_metadata(out)["resumed_episodes"] == 3 and not partial_dir(out).exists()
    fresh = tmp_path / "fresh"
    generate_dataset("heuristic", 3, fresh, seed=2, max_episode_steps=8, progress=False)
    np.testing.assert_array_equal(load_npz(out).observations, load_npz(fresh).observations)
    # --no-resume discards checkpoints (here: recorded with other settings) and starts over
    with monkeypatch.context() as m:
        _interrupt_while_writing(m)
        assert cli.main([*argv[:-5], "--out", str(tmp_path / "again"), "--max-episode-steps", "6", "--quiet"]) == 130
    capsys.readouterr()
    assert cli.main([*argv[:-5], "--out", str(tmp_path / "again"), "--max-episode-steps", "7", "--no-resume",
                     "--quiet"]) == 0
    assert read_metadata(tmp_path / "again")["resumed_episodes"] == 0
    assert read_metadata(tmp_path / "again")["max_episode_steps"] == 7


def test_checkpoints_of_other_code_are_not_resumed(tmp_path, monkeypatch):
    import hsddp_gym.datasets.generation as D

    out = tmp_path / "code"
    with monkeypatch.context() as m:
        _interrupt_while_writing(m)
        with pytest.raises(KeyboardInterrupt):
            generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False)
    monkeypatch.setattr(D, "_code_fingerprint", lambda: "edited")
    with pytest.raises(FileExistsError, match="code_sha256"):
        generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False)
    res = generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False, overwrite=True)
    assert res.resumed_episodes == 0 and out.exists()


def test_one_run_at_a_time_and_stale_temporaries_are_removed(tmp_path):
    import fcntl

    out = tmp_path / "busy"
    partial = partial_dir(out)
    partial.mkdir()
    stale = tmp_path / ".busy.tmp-abcd1234"  # what a killed run's write leaves
    stale.mkdir()
    (stale / "episodes.npz").write_bytes(b"half")
    unrelated = tmp_path / ".busy.tmp-x.keep"
    unrelated.mkdir()
    with open(partial / "lock", "a+") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)  # another live run
        with pytest.raises(FileExistsError, match="another run"):
            generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False)
        assert stale.exists() and not out.exists()
    generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False)
    assert not stale.exists() and unrelated.exists() and not partial.exists()
    umask = os.umask(0)
    os.umask(umask)
    assert (out.stat().st_mode & 0o777) == (0o777 & ~umask)  # not mkdtemp's 0700


def test_failure_with_overwrite_keeps_the_old_dataset(small, tmp_path):
    out = tmp_path / "keep"
    generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False)
    before = (out / "episodes.npz").read_bytes()
    with pytest.raises(RuntimeError, match="boom"):
        generate_dataset(exploding_factory, 2, out, overwrite=True, max_episode_steps=10, progress=False,
                         policy_name="exploding")
    assert (out / "episodes.npz").read_bytes() == before
    assert _leftovers(tmp_path, "keep") == [".keep.partial"]  # episode 0's checkpoint, to resume from


# ------------------------------------------------------------------------------------------ planner fields
def test_mpc_fields_and_feedback_law(tmp_path):
    out = tmp_path / "mpc"
    res = generate_dataset("mpc", 1, out, seed=0, max_episode_steps=10, include_gains=True, progress=False)
    meta = res.metadata
    assert meta["policy"]["name"] == "mpc" and "period" in meta["policy"]["options"]["replan"]
    ep = load_minari(out)[0]
    inf = ep.infos
    T = len(ep.actions)
    period = round(meta["policy"]["options"]["replan"]["period"] / meta["control_dt"])
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
    assert meta["determinism"].endswith("solve_ms") and NONDETERMINISTIC_INFOS == ("solve_ms",)


def test_action_noise_executes_noisy_actions_and_stores_clean_labels(tmp_path):
    import json

    from hsddp_gym.datasets.storage import load_npz

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
    # ref_max_score is the clean policy's score (seeds 5, 6 without noise), not the noisy episodes' mean
    clean = generate_dataset("heuristic", 2, tmp_path / "clean", seed=5, max_episode_steps=25, progress=False)
    assert meta["ref_max_score"] == pytest.approx(np.mean(clean.metadata["episode_returns"]))
    assert meta["ref_max_score"] == pytest.approx(clean.metadata["ref_max_score"])
    assert meta["mean_return"] == pytest.approx(np.mean(meta["episode_returns"])) != meta["ref_max_score"]
    assert "without action noise" in meta["ref_max_score_source"]
    assert load_minari(out).storage.metadata["ref_max_score"] == pytest.approx(meta["ref_max_score"])
    again = tmp_path / "again"
    generate_dataset("heuristic", 2, again, seed=5, max_episode_steps=25, progress=False, action_noise=0.05,
                     workers=2)
    np.testing.assert_array_equal(load_npz(again).actions, d.actions)  # seeded by the episode seed
    with pytest.raises(ValueError):
        generate_dataset("heuristic", 1, tmp_path / "bad", action_noise=-0.1, progress=False)


def test_a_run_killed_before_its_first_episode_does_not_block_other_settings(tmp_path):
    out = tmp_path / "early"
    partial = partial_dir(out)
    partial.mkdir()
    (partial / "settings.json").write_text(json.dumps({"seed": 123}))  # what such a run leaves
    (partial / ".episode-000000.npz.abc123.npz").write_bytes(b"half")  # an interrupted atomic write
    res = generate_dataset("heuristic", 1, out, max_episode_steps=5, progress=False)
    assert res.resumed_episodes == 0 and not partial.exists()

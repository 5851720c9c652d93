"""Learning from demonstrations and RL baselines: BC, DAgger, the SB3 adapter, PPO/SAC smoke runs."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import hsddp_gym  # noqa: F401
from hsddp_gym import cli
from hsddp_gym.datasets.generation import generate_dataset
from hsddp_gym.learning.bc import BCConfig, MLPPolicy, train_bc
from hsddp_gym.learning.dagger import DAggerConfig, dagger_rollout, train_dagger
from hsddp_gym.learning.demonstrations import load_demonstrations
from hsddp_gym.learning.sb3 import as_sb3_policy
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
from hsddp_gym.planners.policies.random_policy import RandomPolicy
from hsddp_gym.rollout.policies import PolicySpec

torch = pytest.importorskip("torch")
torch.set_num_threads(1)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("demos") / "heuristic"
    generate_dataset("heuristic", 3, out, seed=0, max_episode_steps=60, progress=False)
    return out


def make_env(**kw):
    return gym.make("hsddp_gym/Bounding-v0", **kw)


# ------------------------------------------------------------------------------------------ BC
def test_minari_and_npz_give_the_same_demonstrations(dataset):
    a = load_demonstrations(dataset, fmt="minari")
    b = load_demonstrations(dataset / "episodes.npz")
    np.testing.assert_array_equal(a.obs, b.obs)
    np.testing.assert_array_equal(a.actions, b.actions)
    assert a.n_episodes == 3 and len(a) == len(a.actions)
    assert load_demonstrations(dataset, episodes=1, fmt="npz").n_episodes == 1


def test_bc_loss_decreases_and_is_reproducible(dataset, tmp_path):
    demos = load_demonstrations(dataset)
    cfg = BCConfig(hidden=(64, 64), epochs=15, batch_size=64, seed=3)
    policy, hist = train_bc(demos, cfg)
    loss = hist["loss"]
    assert len(loss) == 15 and loss[-1] < 0.5 * loss[0]
    again, hist2 = train_bc(demos, cfg)
    assert hist2["loss"] == loss
    obs = demos.obs[:20]
    np.testing.assert_array_equal(policy.forward(obs), again.forward(obs))
    policy.save(tmp_path / "bc.npz")
    loaded = MLPPolicy.load(tmp_path / "bc.npz")
    a = loaded.act(obs[0])
    assert a.shape == (4,) and a.dtype == np.float32 and np.all(np.abs(a) <= 1)
    np.testing.assert_array_equal(loaded.forward(obs), policy.forward(obs))


def test_dagger_counts_expert_labels(dataset):
    cfg = DAggerConfig(rounds=2, episodes_per_round=2, beta_decay=0.5, max_episode_steps=25,
                       bc=BCConfig(hidden=(32, 32), epochs=3, batch_size=64))
    initial = load_demonstrations(dataset, episodes=1)
    calls = []

    def evaluate(p):
        calls.append(p)
        return {"ok": True}

    res = train_dagger(PolicySpec("heuristic"), cfg, initial=initial, evaluate=evaluate, progress=False)
    h = res.history
    assert [r["round"] for r in h] == [0, 1, 2] and [r["beta"] for r in h] == [1.0, 0.5, 0.25]
    assert h[0]["new_labels"] == len(initial)
    new = sum(r["new_labels"] for r in h[1:])
    assert res.expert_labels == len(initial) + new == len(res.data) == h[-1]["expert_labels"]
    assert all(r["episodes"] == 2 for r in h[1:]) and 0 < new <= 4 * 25
    assert 0.0 <= h[2]["expert_actions_fraction"] <= 1.0 and len(calls) == 3
    # the labels are the expert's actions on the visited observations
    expert = HeuristicPolicy()
    obs = res.data.obs[len(initial):]
    first = obs[: int(np.argmax(res.data.episode[len(initial):] != res.data.episode[len(initial)])) or len(obs)]
    expert.reset()
    np.testing.assert_array_equal(np.stack([expert(o) for o in first]),
                                  res.data.actions[len(initial):len(initial) + len(first)])


def test_dagger_keep_best_returns_the_round_that_fell_least(dataset):
    """keep="best": the learner of the round whose evaluation fell least (ties: the higher mean return, then the
    earlier round) is the result; "last" the last round's; "best" without an evaluation is refused."""
    cfg = DAggerConfig(rounds=3, episodes_per_round=1, max_episode_steps=10, keep="best",
                       bc=BCConfig(hidden=(16,), epochs=2))
    initial = load_demonstrations(dataset, episodes=1)
    scripted = iter([{"falls": 5, "mean_return": 9.0}, {"falls": 1, "mean_return": 2.0},
                     {"falls": 1, "mean_return": 3.0}, {"falls": 1, "mean_return": 3.0}])
    seen = []

    def evaluate(p):
        seen.append(p)
        return next(scripted)

    res = train_dagger(PolicySpec("heuristic"), cfg, initial=initial, evaluate=evaluate, progress=False)
    assert res.selected_round == 2 and res.policy is seen[2] and res.policy.info["selected_round"] == 2
    last = train_dagger(PolicySpec("heuristic"), dataclasses.replace(cfg, keep="last"), initial=initial,
                        evaluate=lambda p: {"falls": 0, "mean_return": 0.0}, progress=False)
    assert last.selected_round == 3
    with pytest.raises(ValueError, match="keep='best' needs evaluate"):
        train_dagger(PolicySpec("heuristic"), cfg, initial=initial, progress=False)
    with pytest.raises(ValueError, match="keep must be one of"):
        DAggerConfig(keep="first")


def test_dagger_without_initial_data_starts_from_expert_episodes():
    cfg = DAggerConfig(rounds=1, episodes_per_round=1, max_episode_steps=10,
                       bc=BCConfig(hidden=(16,), epochs=2))
    res = train_dagger(PolicySpec("heuristic"), cfg, progress=False)
    assert res.history[0]["episodes"] == 1 and res.history[0]["expert_actions_fraction"] == 1.0
    assert res.expert_labels == len(res.data) <= 20


class _RecordActions(gym.Wrapper):
    def __init__(self, env):
        super().__init__(env)
        self.actions = []

    def step(self, action):
        self.actions.append(np.array(action, dtype=np.float32))
        return super().step(action)


def test_dagger_rollout_noise_perturbs_executed_actions_not_labels():
    env = _RecordActions(make_env(max_episode_steps=30))
    expert = HeuristicPolicy.from_env(env)
    O0, A0, _, _, n0 = dagger_rollout(env, None, expert, 1.0, 5, np.random.default_rng(0))
    clean = np.array(env.actions)
    np.testing.assert_array_equal(clean, A0)  # no noise: the executed action is the label
    env.actions = []
    O, A, _, _, n = dagger_rollout(env, None, expert, 1.0, 5, np.random.default_rng(0), noise=0.1)
    executed = np.array(env.actions)
    assert n == len(O) and len(executed) == len(A)
    assert np.all(np.abs(executed) <= 1.0)
    dev = executed - A
    assert 0.05 < float(np.std(dev)) < 0.15  # the executed actions carry the noise ...
    assert not np.allclose(O[1:min(len(O), len(O0))], O0[1:min(len(O), len(O0))])  # ... which moves the states
    # ... and the labels are the clean expert actions on the visited observations
    replay = HeuristicPolicy.from_env(env)
    replay.reset()
    np.testing.assert_array_equal(np.stack([replay(o) for o in O]), A)
    with pytest.raises(ValueError):
        DAggerConfig(rollout_noise=-0.1)


def test_train_bc_warm_start_keeps_init_normalization_and_weights(dataset):
    demos = load_demonstrations(dataset)
    cfg = BCConfig(hidden=(32, 32), epochs=3, batch_size=64, seed=1)
    first, _ = train_bc(demos.first_episodes(1), cfg)
    tiny = BCConfig(hidden=(32, 32), epochs=1, batch_size=64, seed=2, lr=1e-9)
    warm, _ = train_bc(demos, tiny, init=first)
    np.testing.assert_array_equal(warm.obs_mean, first.obs_mean)
    np.testing.assert_array_equal(warm.obs_std, first.obs_std)
    np.testing.assert_allclose(warm.forward(demos.obs[:10]), first.forward(demos.obs[:10]), atol=1e-5)
    cold, _ = train_bc(demos, tiny)
    assert not np.allclose(cold.obs_mean, first.obs_mean)
    assert not np.allclose(cold.forward(demos.obs[:10]), first.forward(demos.obs[:10]), atol=1e-3)
    with pytest.raises(ValueError):
        train_bc(demos, BCConfig(hidden=(16,), epochs=1), init=first)


def test_dagger_warm_start_and_noise_options():
    cfg = DAggerConfig(rounds=2, episodes_per_round=1, max_episode_steps=15, rollout_noise=0.05, warm_start=True,
                       bc=BCConfig(hidden=(16,), epochs=2))
    learners = []
    res = train_dagger(PolicySpec("heuristic"), cfg, progress=False, evaluate=lambda p: learners.append(p) or {})
    assert len(learners) == 3 and res.policy is learners[-1]
    for p in learners[1:]:  # warm start: the round-0 standardization is kept
        np.testing.assert_array_equal(p.obs_mean, learners[0].obs_mean)
    cold = train_dagger(PolicySpec("heuristic"), dataclasses.replace(cfg, warm_start=False), progress=False)
    assert not np.array_equal(cold.policy.obs_mean, learners[0].obs_mean)
    # the noise changes the relabelled states, not round 0
    quiet = train_dagger(PolicySpec("heuristic"), dataclasses.replace(cfg, rollout_noise=0.0), progress=False)
    n0 = res.history[0]["new_labels"]
    np.testing.assert_array_equal(quiet.data.obs[:n0], res.data.obs[:n0])
    m = min(len(quiet.data), len(res.data))
    assert not np.array_equal(quiet.data.obs[n0:m], res.data.obs[n0:m])
    assert res.expert_labels == len(res.data)


def test_dagger_rollout_steps_truncates_relabelling_rollouts_only():
    env = make_env(max_episode_steps=30)
    expert = HeuristicPolicy.from_env(env)
    O, A, _, _, _ = dagger_rollout(env, None, expert, 1.0, 2, np.random.default_rng(0), max_steps=7)
    assert len(O) == len(A) == 7
    cfg = DAggerConfig(rounds=2, episodes_per_round=2, max_episode_steps=20, rollout_steps=6,
                       bc=BCConfig(hidden=(16,), epochs=2))
    res = train_dagger(PolicySpec("heuristic"), cfg, progress=False)
    h = res.history
    assert h[0]["new_labels"] == 40  # round 0: full expert episodes (the heuristic does not fall in 20 steps)
    assert all(r["new_labels"] <= 12 for r in h[1:]) and res.expert_labels == len(res.data) == 40 + sum(
        r["new_labels"] for r in h[1:])
    with pytest.raises(ValueError):
        DAggerConfig(rollout_steps=0)


def test_cli_dagger_flags():
    args = cli.build_parser().parse_args(["train", "--algo", "dagger", "--out", "x", "--rollout-noise", "0.04",
                                          "--warm-start", "--rollout-steps", "200"])
    assert args.rollout_noise == 0.04 and args.warm_start is True and args.rollout_steps == 200
    args = cli.build_parser().parse_args(["train", "--algo", "dagger", "--out", "x"])
    assert args.rollout_noise == 0.0 and args.warm_start is False and args.rollout_steps is None


# ------------------------------------------------------------------------------------------ SB3 adapter
def test_sb3_adapter_returns_the_callables_actions():
    from stable_baselines3.common.policies import BasePolicy

    env = make_env(max_episode_steps=40)
    reference = HeuristicPolicy.from_env(env)
    adapted = as_sb3_policy(HeuristicPolicy.from_env(env), env.observation_space, env.action_space)
    assert isinstance(adapted, BasePolicy)
    obs, _ = env.reset(seed=4)
    reference.reset()
    start = True
    for _ in range(40):
        expected = reference(obs)
        got, state = adapted.predict(obs, episode_start=np.array([start]), deterministic=True)
        assert state is None and got.shape == (4,) and got.dtype == np.float32
        np.testing.assert_array_equal(got, expected)
        start = False
        obs, _, term, trunc, _ = env.step(expected)
        if term or trunc:
            break
    # _predict on a batch tensor and a plain (memoryless) callable
    batch = np.stack([obs, obs]).astype(np.float32)
    fn = RandomPolicy(seed=0)
    plain = as_sb3_policy(lambda o: np.tanh(o[:4]).astype(np.float32), env.observation_space, env.action_space)
    out = plain._predict(torch.as_tensor(batch)).numpy()
    np.testing.assert_array_equal(out, np.tanh(batch[:, :4]))
    acts, _ = plain.predict(batch)
    np.testing.assert_array_equal(acts, np.tanh(batch[:, :4]))
    with pytest.raises(TypeError):
        as_sb3_policy(fn, gym.spaces.Discrete(2), env.action_space)


def test_evaluate_policy_runs_the_adapter_and_the_raw_policy():
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor

    results = []
    for wrap in (True, False):
        env = Monitor(make_env(max_episode_steps=40))
        env.reset(seed=0)
        policy = HeuristicPolicy.from_env(env)
        model = as_sb3_policy(policy, env.observation_space, env.action_space) if wrap else policy
        rewards, lengths = evaluate_policy(model, env, n_eval_episodes=2, deterministic=True,
                                           return_episode_rewards=True)
        assert len(rewards) == 2 and all(0 < n <= 40 for n in lengths)
        results.append(rewards)
    np.testing.assert_allclose(results[0], results[1])


# ------------------------------------------------------------------------------------------ CLI training
def test_cli_bc_writes_policy_and_evaluation(dataset, tmp_path):
    out = tmp_path / "bc"
    rc = cli.main(["train", "--algo", "bc", "--dataset", str(dataset), "--epochs", "3", "--seed", "0",
                   "--out", str(out), "--eval-episodes", "2", "--max-episode-steps", "30", "--curve", "1,3",
                   "--quiet"])
    assert rc == 0
    import json

    s = json.loads((out / "summary.json").read_text())
    assert s["demonstrations"] == 3 and s["eval"]["episodes"] == 2 and len(s["curve"]) == 2
    assert (out / "policy.npz").exists() and (out / "curve.csv").exists()


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_cli_ppo_sac_smoke(algo, tmp_path):
    import json

    from hsddp_gym.learning.sb3 import load_trained_policy

    out = tmp_path / algo
    argv = ["train", "--algo", algo, "--steps", "300", "--seed", "1", "--out", str(out), "--max-episode-steps",
            "50", "--eval-freq", "200", "--eval-episodes", "2", "--quiet"]
    if algo == "sac":
        argv += ["--learning-starts", "100"]
    assert cli.main(argv) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["algo"] == algo and s["steps"] >= 300 and s["seed"] == 1 and s["wall_time_s"] > 0
    assert s["eval"]["episodes"] == 2
    for name in ("model.zip", "train.monitor.csv", "curve.csv", "evaluations.npz", "eval_curve.csv"):
        assert (out / name).exists(), name
    if algo == "ppo":
        assert (out / "vecnormalize.npz").exists() and (out / "vecnormalize.pkl").exists()
        assert s["hyperparameters"]["n_steps"] == 512 and s["hyperparameters"]["learning_rate"] == 9.80828e-5
        assert s["preset"] == "hopper"
    else:
        assert s["hyperparameters"]["learning_starts"] == 100
    # the weights-only reload acts like the SB3 model
    policy = load_trained_policy(out)
    env = make_env()
    obs, _ = env.reset(seed=0)
    from stable_baselines3 import PPO, SAC

    ref = (PPO if algo == "ppo" else SAC).load(out / "model.zip", device="cpu")
    expected, _ = ref.predict(policy.normalize(obs), deterministic=True)
    np.testing.assert_allclose(policy.act(obs), np.clip(expected, -1, 1), atol=1e-6)
    assert s["eval_stochastic"]["episodes"] == 2
    # stochastic actions: draws of the policy's own distribution from a generator seeded at every reset
    noisy = load_trained_policy(out, deterministic=False, noise_seed=3)
    first = [noisy.act(obs) for _ in range(3)]
    noisy.reset()
    np.testing.assert_array_equal(first, [noisy.act(obs) for _ in range(3)])   # the same draws after a reset
    assert not np.allclose(first[0], first[1]) and not np.allclose(first[0], policy.act(obs))
    assert np.all(np.abs(first) <= 1.0)
    other = load_trained_policy(out, deterministic=False, noise_seed=4)
    assert not np.allclose(other.act(obs), first[0])
    with pytest.raises(TypeError, match="deterministic"):
        load_trained_policy(out, deterministic="no")
    # the best checkpoint of the training-time evaluations, with the observation statistics of that moment
    ev = np.load(out / "evaluations.npz")
    best = s["best_checkpoint"]
    means = ev["results"].mean(axis=1)
    assert best["mean_return"] == pytest.approx(means.max())
    assert best["env_step"] == int(ev["timesteps"][int(np.argmax(means))])
    assert s["eval_best"]["episodes"] == 2 and "best_model.zip" in s["files"]
    assert load_trained_policy(out, checkpoint="best").act(obs).shape == (4,)
    with pytest.raises(ValueError, match="checkpoint"):
        load_trained_policy(out, checkpoint="last")


def test_bc_with_gait_clock_features_has_memory_and_round_trips(dataset, tmp_path):
    from hsddp_gym.learning.features import build_inputs, gait_clock_features, make_gait_clock

    demos = load_demonstrations(dataset)
    cfg = BCConfig(hidden=(32,), epochs=3, batch_size=64, features="gait_clock", lr_decay=True)
    policy, hist = train_bc(demos, cfg)
    assert policy.obs_mean.shape == (17 + 7,) and len(hist["loss"]) == 3
    ep0 = demos.obs[demos.episode == 0]
    clock = make_gait_clock()
    # the inputs of each episode start from a reset clock
    Z = build_inputs(demos, cfg, clock)
    np.testing.assert_array_equal(Z[demos.episode == 1][:, 17:], gait_clock_features(demos.obs[demos.episode == 1],
                                                                                      clock))
    # acting rebuilds the same features step by step; reset() restarts the clock
    policy.reset()
    acts = np.array([policy.act(o) for o in ep0[:30]])
    np.testing.assert_allclose(acts, policy.forward(Z[:30]).astype(np.float32), atol=1e-6)
    assert policy.clock.phase is not None
    policy.reset()
    assert policy.clock.phase is None
    policy.save(tmp_path / "bc.npz")
    loaded = MLPPolicy.load(tmp_path / "bc.npz")
    assert loaded.config.features == "gait_clock" and loaded.clock.durations == clock.durations
    np.testing.assert_array_equal(np.array([loaded.act(o) for o in ep0[:30]]), acts)
    twin = loaded.spawn()
    assert twin.clock is not loaded.clock
    with pytest.raises(ValueError):
        BCConfig(features="history")


def test_demonstration_labels_are_the_clean_actions_of_a_noisy_dataset(tmp_path):
    out = tmp_path / "dart"
    generate_dataset("heuristic", 2, out, seed=0, max_episode_steps=30, progress=False, action_noise=0.1)
    for fmt in ("minari", "npz"):
        demos = load_demonstrations(out, fmt=fmt)
        policy = HeuristicPolicy.from_env(make_env())
        ep0 = demos.obs[demos.episode == 0]
        policy.reset()
        clean = np.array([policy(o) for o in ep0])
        np.testing.assert_allclose(demos.actions[demos.episode == 0], clean, atol=1e-6)


# ------------------------------------------------------------------------------------------ DAgger with the MPC
def test_cli_dagger_relabels_the_learners_states_with_the_mpc(tmp_path):
    """beta = 0: the learner alone drives the round-1 rollouts; every visited observation is labelled with
    the MPC expert's action there (a fresh MPC replaying those observations, told after each one the action
    the round-0 learner sent, gives the same labels; believing its own actions sent, it does not)."""
    import json

    from hsddp_gym.planners.policies.mpc import MPCPolicy
    from hsddp_gym.util.io import read_npz

    out = tmp_path / "dagger"
    rc = cli.main(["train", "--algo", "dagger", "--expert", "mpc", "--rounds", "1", "--episodes-per-round", "1",
                   "--beta-decay", "0", "--max-episode-steps", "16", "--epochs", "2", "--hidden", "16",
                   "--eval-episodes", "1", "--seed", "0", "--out", str(out), "--quiet"])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["expert"]["name"] == "mpc" and [h["round"] for h in s["history"]] == [0, 1]
    assert s["history"][0]["expert_actions_fraction"] == 1.0  # round 0: the MPC's own episode
    assert s["history"][1]["expert_actions_fraction"] == 0.0  # round 1: the learner's actions only
    assert s["expert_labels"] == s["transitions"] and s["eval"]["episodes"] == 1
    d = read_npz(out / "dagger_data.npz")
    learner_obs, labels = d["obs"][d["episode"] == 1], d["actions"][d["episode"] == 1]
    assert 0 < len(learner_obs) <= 16
    from hsddp_gym.datasets.recording import inform_sent_action
    from hsddp_gym.learning.demonstrations import Demonstrations
    from hsddp_gym.planners.policies.base import EnvInterface

    r0 = d["episode"] == 0  # round 0's data; retrained as in the run (same config and seed): the round-1 learner
    learner0, _ = train_bc(Demonstrations(d["obs"][r0], d["actions"][r0], d["episode"][r0]),
                           BCConfig(epochs=2, hidden=(16,), seed=0), EnvInterface.from_env(make_env()))
    mpc = MPCPolicy.from_env(make_env())
    mpc.reset()
    replay = []
    for o in learner_obs:
        replay.append(mpc(o))
        inform_sent_action(mpc, learner0(o))
    np.testing.assert_array_equal(np.stack(replay), labels)
    mpc.reset()
    assert not np.array_equal(np.stack([mpc(o) for o in learner_obs]), labels)
    # the learner's states are not the expert's own trajectory from the same reset
    env = make_env(max_episode_steps=16)
    obs, _ = env.reset(seed=1000)  # round 1, episode 0: seed + 1000 * round + j
    np.testing.assert_array_equal(obs, learner_obs[0])
    expert_obs = [obs]
    mpc.reset()
    for _ in range(len(learner_obs) - 1):
        obs, *_ = env.step(mpc(obs))
        expert_obs.append(obs)
    assert not np.allclose(np.stack(expert_obs), learner_obs)


# ------------------------------------------------------------------------------------------ the comparison
def _png_width(path) -> int:
    import struct

    with open(path, "rb") as f:
        head = f.read(24)
    return struct.unpack(">I", head[16:20])[0]  # the IHDR chunk's width


def test_compare_policies_writes_the_table_and_the_curves(dataset, tmp_path):
    import importlib.util
    import json
    from pathlib import Path

    runs = tmp_path / "runs"
    assert cli.main(["train", "--algo", "bc", "--dataset", str(dataset), "--epochs", "2", "--hidden", "16",
                     "--curve", "1,3", "--eval-episodes", "1", "--max-episode-steps", "20", "--out",
                     str(runs / "bc"), "--quiet"]) == 0
    assert cli.main(["train", "--algo", "dagger", "--expert", "heuristic", "--rounds", "1", "--episodes-per-round",
                     "1", "--max-episode-steps", "20", "--epochs", "2", "--hidden", "16", "--eval-episodes", "1",
                     "--out", str(runs / "dagger"), "--quiet"]) == 0
    assert cli.main(["train", "--algo", "ppo", "--steps", "256", "--max-episode-steps", "30", "--eval-freq", "128",
                     "--eval-episodes", "1", "--out", str(runs / "ppo"), "--quiet"]) == 0
    path = Path(__file__).resolve().parents[1] / "experiments" / "compare_policies.py"
    spec = importlib.util.spec_from_file_location("compare_policies", path)
    compare = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(compare)
    out = tmp_path / "compare"
    assert compare.main(["--out", str(out), "--runs", str(runs), "--episodes", "2", "--max-episode-steps", "30",
                         "--policies", "heuristic", "random", "bc", "dagger", "ppo", "sac"]) == 0
    table = (out / "compare.md").read_text()
    for name in ("heuristic", "random", "bc", "dagger", "ppo"):
        assert f"| {name} |" in table, name
    assert "skipped sac" in table and "![curves](curves.png)" in table and (out / "curves.png").exists()
    both_wide = _png_width(out / "curves.png")
    assert compare.plot_curves({"ppo": [runs / "ppo"]}, tmp_path / "rl_only", 1460.0)
    assert _png_width(tmp_path / "rl_only" / "curves.png") < 0.7 * both_wide  # no empty BC / DAgger panel
    rows = {r["policy"]: r for r in json.loads((out / "compare.json").read_text())["rows"]}
    assert rows["ppo"]["samples"].endswith("env steps") and rows["ppo"]["train_time_s"] > 0
    assert "of the MPC's" in table and rows["ppo"]["of_mpc"] is None
    assert "demos" in rows["bc"]["samples"] and "expert labels" in rows["dagger"]["samples"]
    # PPO's own Gaussian draws instead of its mean: another result, the same on a rerun
    rerun = []
    for k in range(2):
        assert compare.main(["--out", str(tmp_path / f"stoch{k}"), "--runs", str(runs), "--episodes", "2",
                             "--max-episode-steps", "30", "--policies", "ppo", "--rl-actions", "stochastic"]) == 0
        assert "ppo/sac: stochastic actions" in (tmp_path / f"stoch{k}" / "compare.md").read_text()
        rerun.append(json.loads((tmp_path / f"stoch{k}" / "compare.json").read_text())["rows"][0]["mean_return"])
    assert rerun[0] == rerun[1] != rows["ppo"]["mean_return"]
    # the best checkpoint of the training-time evaluations
    assert compare.main(["--out", str(tmp_path / "best"), "--runs", str(runs), "--episodes", "2",
                         "--max-episode-steps", "30", "--policies", "ppo", "--rl-checkpoint", "best"]) == 0
    assert "ppo/sac: best checkpoint" in (tmp_path / "best" / "compare.md").read_text()
    assert all(r["episodes"] == 2 and r["mean_episode_length"] <= 30 for r in rows.values())


def test_compare_policies_over_training_seeds_reports_a_95_interval(tmp_path):
    import importlib.util
    import json
    from pathlib import Path

    runs = tmp_path / "runs"
    for seed in (0, 1):
        assert cli.main(["train", "--algo", "ppo", "--steps", "128", "--max-episode-steps", "20", "--eval-freq", "64",
                         "--eval-episodes", "1", "--seed", str(seed), "--out", str(runs / "ppo" / f"seed{seed}"),
                         "--quiet"]) == 0
    path = Path(__file__).resolve().parents[1] / "experiments" / "compare_policies.py"
    spec = importlib.util.spec_from_file_location("compare_policies", path)
    compare = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(compare)
    assert [p.name for p in compare.expand_runs("ppo", [runs / "ppo"])] == ["seed0", "seed1"]
    out = tmp_path / "compare"
    assert compare.main(["--out", str(out), "--ppo", str(runs / "ppo"), "--episodes", "2", "--max-episode-steps",
                         "20", "--policies", "ppo"]) == 0
    row = json.loads((out / "compare.json").read_text())["rows"][0]
    assert row["training_seeds"] == 2 and row["episodes"] == 4 and len(row["seed_mean_returns"]) == 2
    from hsddp_gym.learning.reporting import mean_ci95

    assert row["mean_return"] == pytest.approx(mean_ci95(row["seed_mean_returns"])[0])
    assert row["ci95"] == pytest.approx(mean_ci95(row["seed_mean_returns"])[1])
    assert "(95 % CI)" in (out / "compare.md").read_text()
    # more rows of a kind: --learned NAME@TAG=DIR, a label given again adds a training seed to its row
    out2 = tmp_path / "compare2"
    assert compare.main(["--out", str(out2), "--ppo", str(runs / "ppo" / "seed0"), "--episodes", "2",
                         "--max-episode-steps", "20", "--policies", "ppo", "--learned",
                         f"ppo@b={runs / 'ppo' / 'seed1'}", "--learned", f"ppo@b={runs / 'ppo' / 'seed0'}",
                         "--learned", f"sac@none={tmp_path / 'nothing'}"]) == 0
    rows = {r["policy"]: r for r in json.loads((out2 / "compare.json").read_text())["rows"]}
    assert set(rows) == {"ppo", "ppo@b"} and rows["ppo@b"]["training_seeds"] == 2
    steps = sorted(json.loads((runs / "ppo" / f"seed{k}" / "summary.json").read_text())["steps"] for k in (0, 1))
    assert rows["ppo@b"]["samples"] == (f"{steps[0]:,} env steps" if steps[0] == steps[1] else
                                        f"{steps[0]:,}–{steps[1]:,} env steps")
    assert rows["ppo"]["of_mpc"] is None  # no MPC row to compare with
    assert rows["ppo@b"]["seed_mean_returns"] == row["seed_mean_returns"][::-1]  # the same runs, evaluated alike
    assert rows["ppo"]["seed_mean_returns"] == row["seed_mean_returns"][:1]
    table = (out2 / "compare.md").read_text()
    assert "| ppo@b |" in table and "skipped sac@none" in table and (out2 / "curves.png").exists()
    for bad in ("ppo=x", "ppo@=x", "td3@a=x", "ppo@a", "mpc@a=x"):
        with pytest.raises(SystemExit):
            compare.main(["--out", str(tmp_path / "bad"), "--learned", bad])


def test_mean_ci95_and_curve_band():
    from hsddp_gym.learning.reporting import curve_band, mean_ci95

    m, h = mean_ci95([1.0, 2.0, 3.0])
    assert m == 2.0 and h == pytest.approx(4.303 * 1.0 / np.sqrt(3))
    assert np.isnan(mean_ci95([5.0])[1])
    with pytest.raises(ValueError, match="must not be empty"):
        mean_ci95([])
    with pytest.raises(ValueError, match="finite"):
        mean_ci95([1.0, float("nan")])
    band = curve_band([([0, 10], [0, 10]), ([0, 5, 10], [2, 7, 12])], points=11)
    np.testing.assert_allclose(band["x"], np.arange(11.0))
    np.testing.assert_allclose(band["mean"], np.arange(11.0) + 1.0)
    half = 12.706 * np.std([0.0, 2.0], ddof=1) / np.sqrt(2)
    np.testing.assert_allclose(band["high"] - band["mean"], half)
    assert band["seeds"] == 2
    with pytest.raises(ValueError, match="share no x range"):
        curve_band([([0, 1], [0, 0]), ([2, 3], [0, 0])])


def test_rl_presets():
    from hsddp_gym.learning.sb3 import PPO_HYPERPARAMS, hyperparameters

    hp = hyperparameters("ppo")
    assert hp["learning_rate"] == 9.80828e-5 and hp["batch_size"] == 32 and hp["gamma"] == 0.999
    assert hyperparameters("ppo", preset="halfcheetah") == PPO_HYPERPARAMS
    assert hyperparameters("ppo", {"n_envs": 4})["n_envs"] == 4
    assert hyperparameters("sac")["learning_starts"] == 10_000
    par = hyperparameters("ppo", preset="parallel")  # legged_gym's massively parallel PPO, on a CPU
    assert par["n_envs"] * par["n_steps"] == 4 * par["batch_size"] and par["normalize"]
    with pytest.raises(ValueError, match="preset must be one of"):
        hyperparameters("sac", preset="parallel")
    with pytest.raises(ValueError, match="preset must be one of"):
        hyperparameters("ppo", preset="walker")


def test_rl_trains_in_bounding_and_every_task_with_an_expert():
    """PPO / SAC take Bounding-v0 and every task env whose task has a plan-tracking expert (what ``--residual``
    builds on); the terrain task (no expert) is refused by name."""
    from hsddp_gym.learning.sb3 import ENV_ID, ENV_IDS
    from hsddp_gym.learning.sb3.training import check_env_id
    from hsddp_gym.registry import TASKS

    assert set(ENV_IDS) == {ENV_ID} | {t.env_id for t in TASKS.values() if t.expert is not None}
    for env_id in ENV_IDS:
        assert check_env_id(env_id) == env_id
    with pytest.raises(ValueError, match="Terrain-v0"):
        check_env_id("hsddp_gym/Terrain-v0")


def test_bc_input_noise_teaches_the_clean_label_from_a_noisy_measurement(tmp_path):
    """With ``input_noise`` the network is trained on noisy positions and velocities against the clean labels: a label
    that jumps with one velocity is learned as a smooth ramp over the noise's width (the expert's expected action
    given a noisy reading), without it as the step; the setting is validated and kept in ``policy.npz``."""
    from hsddp_gym.learning.bc import MLPPolicy
    from hsddp_gym.learning.demonstrations import Demonstrations

    rng = np.random.default_rng(0)
    obs = rng.uniform(-1.0, 1.0, (4000, 17))  # every entry varies; the label reads one observed velocity
    actions = np.zeros((len(obs), 4))
    actions[:, 0] = np.where(obs[:, 7] > 0.0, 0.8, -0.8)  # a step in that velocity
    demos = Demonstrations(obs, actions, np.zeros(len(obs), dtype=np.int64))
    probe = np.zeros((3, 17))
    probe[:, 7] = [-0.05, 0.0, 0.05]  # the others at their mean

    def slope(config):
        policy, _ = train_bc(demos, config)
        a = np.stack([policy(o) for o in probe])[:, 0]
        return (a[2] - a[0]) / 0.1, policy

    base = dict(hidden=(32, 32), epochs=30, seed=0)
    sharp, _ = slope(BCConfig(**base))
    smooth, policy = slope(BCConfig(**base, input_noise=(0.0, 0.3)))
    assert sharp > 6.0 and 0.5 < smooth < 3.5  # a ramp of width ~0.3: slope ~ 1.6 / (0.3 sqrt(2 pi)) ~ 2.1
    policy.save(tmp_path / "p.npz")
    assert MLPPolicy.load(tmp_path / "p.npz").config.input_noise == (0.0, 0.3)
    for bad in ((0.1,), (-0.1, 0.1), (0.1, float("nan")), "0.1 0.1"):
        with pytest.raises(ValueError, match="input_noise"):
            BCConfig(input_noise=bad)

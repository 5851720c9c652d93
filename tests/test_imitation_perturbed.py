"""Demonstrations and DAgger rollouts under the perturbation conditions: the expert on the true state,
the learner's (perturbed) observation stored, the condition and target speed of every episode recorded."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hsddp_gym.datasets.collection import collect_episodes, episode_conditions
from hsddp_gym.datasets.recording import inform_sent_action
from hsddp_gym.envs.perturbations import check_conditions, make_env, true_observation, wrapper_info_keys
from hsddp_gym.rollout.policies import PolicySpec


def test_true_observation_is_the_env_observation_without_its_noise():
    env = make_env("default", max_episode_steps=20)
    obs, _ = env.reset(seed=3)
    np.testing.assert_array_equal(true_observation(env), obs)
    for _ in range(5):
        obs, *_ = env.step(np.full(4, 0.2, dtype=np.float32))
        np.testing.assert_array_equal(true_observation(env), obs)
    noisy = make_env("obs_noise", max_episode_steps=20)
    nobs, _ = noisy.reset(seed=3)
    obs, _ = env.reset(seed=3)  # same seed: same true state
    np.testing.assert_array_equal(true_observation(noisy), obs)
    assert not np.array_equal(nobs, obs)


def test_wrapper_info_keys_and_condition_names():
    assert wrapper_info_keys(make_env("push")) == {"push"}
    assert wrapper_info_keys(make_env("delay_10ms")) == {"executed_action"}
    assert wrapper_info_keys(make_env("default")) == frozenset()
    assert check_conditions(["push", "push", "default"]) == ("push", "push", "default")
    with pytest.raises(ValueError, match=r"--condition: unknown condition\(s\) \['pushed'\]; allowed: \['default'"):
        check_conditions(["push", "pushed"], "--condition")
    with pytest.raises(ValueError, match="non-empty list"):
        check_conditions("push")
    assert episode_conditions(("a", "b"), 5) == ["a", "b", "a", "b", "a"]
    assert episode_conditions(None, 2) == [None, None]


def test_under_observation_noise_the_expert_acts_on_the_true_state():
    """Observation noise does not change the dynamics: an expert acting on the true state drives the same
    trajectory as in the plain env, while the stored observations are the noisy ones."""
    plain = collect_episodes(PolicySpec("heuristic"), 1, seed=11, max_episode_steps=60, progress=False)[0]
    noisy, fast = collect_episodes(PolicySpec("heuristic"), 2, seed=11, max_episode_steps=60, progress=False,
                                   conditions=["obs_noise", "speed_2.0"])
    np.testing.assert_array_equal(noisy.actions, plain.actions)
    np.testing.assert_array_equal(noisy.infos["qpos"], plain.infos["qpos"])
    assert np.abs(noisy.observations - plain.observations).max() > 0.01
    assert fast.seed == 12 and not np.array_equal(fast.actions[:40], plain.actions[:40])


def test_push_and_delay_episodes_record_the_env_schema():
    eps = collect_episodes(PolicySpec("heuristic"), 2, seed=0, max_episode_steps=15, progress=False,
                           conditions=["push", "delay_10ms"])
    base = collect_episodes(PolicySpec("heuristic"), 1, seed=0, max_episode_steps=15, progress=False)[0]
    for ep in eps:
        assert set(ep.infos) == set(base.infos) and ep.length == 15
    with pytest.raises(ValueError, match="sets \\['target_speed'\\] itself"):
        collect_episodes(PolicySpec("heuristic"), 1, env_kwargs={"target_speed": 1.5}, conditions=["speed_2.0"],
                         progress=False)


def test_dataset_metadata_give_each_episode_its_condition_and_target_speed(tmp_path):
    from hsddp_gym.datasets.generation import generate_dataset
    from hsddp_gym.learning.demonstrations import load_demonstrations

    out = tmp_path / "ds"
    generate_dataset("heuristic", 3, out, seed=5, max_episode_steps=12, progress=False,
                     conditions=["speed_0.5", "obs_noise"])
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["episode_conditions"] == ["speed_0.5", "obs_noise", "speed_0.5"]
    assert meta["episode_target_speeds"] == [0.5, 1.0, 0.5]
    assert meta["conditions"]["definitions"]["obs_noise"]["observation_noise"] == [0.01, 0.1]
    for fmt in ("npz", "minari"):
        d = load_demonstrations(out, fmt=fmt)
        np.testing.assert_array_equal(d.target_speed, np.repeat([0.5, 1.0, 0.5], 12))


def test_an_mpc_expert_is_told_the_action_sent_in_its_place():
    """The MPC predicts the state from the actions it believes were sent (state filter, latency compensation):
    after being told another action, its next decision differs from the one it takes believing its own."""
    from hsddp_gym.planners.policies.heuristic import HeuristicPolicy
    from hsddp_gym.planners.policies.mpc import MPCPolicy

    env = make_env("delay_10ms", max_episode_steps=50)
    obs, _ = env.reset(seed=2)
    told, own = MPCPolicy.from_env(env), MPCPolicy.from_env(env)
    a = told(obs)
    np.testing.assert_array_equal(a, own(obs))
    sent = -np.ones(4, dtype=np.float32)
    inform_sent_action(told, sent)
    obs, *_ = env.step(sent)
    told(obs), own(obs)
    assert not np.allclose(told.last_prediction, own.last_prediction)
    inform_sent_action(HeuristicPolicy.from_env(env), sent)  # no memory of actions: nothing to do


def test_dagger_under_conditions_labels_the_true_state_and_keeps_the_target_speed():
    pytest.importorskip("torch")
    from hsddp_gym.learning.bc import BCConfig
    from hsddp_gym.learning.dagger import DAggerConfig, train_dagger

    cfg = DAggerConfig(rounds=1, episodes_per_round=2, beta_decay=0.0, max_episode_steps=30, rollout_steps=20,
                       conditions=("obs_noise", "speed_2.0"), bc=BCConfig(hidden=(16,), epochs=2, speed_input=True))
    res = train_dagger(PolicySpec("heuristic"), cfg, progress=False)
    d = res.data
    assert d.n_episodes == 4 and len(d) == 30 + 30 + 20 + 20
    np.testing.assert_array_equal(d.target_speed, np.repeat([1.0, 2.0, 1.0, 2.0], [30, 30, 20, 20]))
    # round 0 (expert only) under observation noise: the labels are the plain-env expert's actions
    plain = collect_episodes(PolicySpec("heuristic"), 1, seed=cfg.seed, max_episode_steps=30, progress=False)[0]
    np.testing.assert_array_equal(d.actions[:30], plain.actions)
    assert np.abs(d.obs[:30] - plain.observations[:30]).max() > 0.01
    two = train_dagger(PolicySpec("heuristic"), cfg, progress=False, workers=2)
    np.testing.assert_array_equal(two.data.obs, d.obs)
    np.testing.assert_array_equal(two.data.actions, d.actions)
    with pytest.raises(ValueError, match="unknown condition"):
        DAggerConfig(conditions=("nope",))
    with pytest.raises(ValueError, match="sets \\['target_speed'\\] itself"):
        train_dagger(PolicySpec("heuristic"), cfg, env_kwargs={"target_speed": 1.0}, progress=False)


def test_dagger_in_a_task_env_runs_the_condition_built_for_the_task():
    """A task's DAgger rollouts run in the condition built for the task (its push window and sizes, the task's
    expert labelling the true state under observation noise); a condition the task refuses is an error naming it."""
    pytest.importorskip("torch")
    from hsddp_gym.datasets.collection import make_env as make_collection_env
    from hsddp_gym.envs.perturbations.wrappers import ObservationNoise, RandomPush
    from hsddp_gym.learning.bc import BCConfig
    from hsddp_gym.learning.dagger import DAggerConfig, train_dagger
    from hsddp_gym.registry import TASKS

    flip = TASKS["backflip"]
    env = make_collection_env(condition="push", env_id=flip.env_id)
    pushes = env
    while not isinstance(pushes, RandomPush):
        pushes = pushes.env
    assert pushes.unwrapped.spec.id == flip.env_id and tuple(pushes.time_range) == tuple(flip.push_window)
    env.close()
    assert isinstance(make_collection_env(condition="obs_noise", env_id=flip.env_id), ObservationNoise)
    with pytest.raises(ValueError, match="conditions: condition 'speed_2.0' does not apply to hsddp_gym/Backflip"):
        DAggerConfig(env_id=flip.env_id, conditions=("speed_2.0",))
    cfg = DAggerConfig(rounds=0, episodes_per_round=1, max_episode_steps=20, env_id=flip.env_id,
                       conditions=("obs_noise",), bc=BCConfig(hidden=(16,), epochs=1))
    res = train_dagger(PolicySpec("expert", env_id=flip.env_id), cfg, progress=False)
    plain = collect_episodes(PolicySpec("expert", env_id=flip.env_id), 1, seed=cfg.seed, max_episode_steps=20,
                             progress=False, env_id=flip.env_id)[0]
    np.testing.assert_array_equal(res.data.actions, plain.actions)  # labels: the expert on the true state
    assert np.abs(res.data.obs - plain.observations[:20]).max() > 0.01  # stored: what the learner saw


def test_dagger_behind_the_estimator_stores_what_the_learner_sees(tmp_path):
    """``DAggerConfig.estimator``: under a 10 ms delay the stored inputs are the states the actions will act on (the
    estimate predicted two control steps ahead), not the observations; the queue option is refused with it."""
    pytest.importorskip("torch")
    from hsddp_gym.learning.bc import BCConfig
    from hsddp_gym.learning.dagger import DAggerConfig, train_dagger
    from hsddp_gym.planners.policies.base import EnvInterface
    from hsddp_gym.planners.policies.estimated_state import EstimatedStatePolicy
    from hsddp_gym.planners.policies.heuristic import HeuristicPolicy

    cfg = DAggerConfig(rounds=1, episodes_per_round=1, beta_decay=0.0, max_episode_steps=40, conditions=("delay_10ms",),
                       estimator=True, bc=BCConfig(hidden=(16,), epochs=2))
    res = train_dagger(PolicySpec("heuristic"), cfg, progress=False)
    assert res.policy.info["estimator"] is True
    # a learner trained behind the estimator acts behind it wherever it is loaded by name
    from hsddp_gym.rollout.policies import make_policy

    res.policy.save(tmp_path / "policy.npz")
    (tmp_path / "summary.json").write_text(json.dumps({"algo": "dagger"}))
    loaded = make_policy(f"dagger:{tmp_path}", make_env("delay_5ms"))
    assert isinstance(loaded, EstimatedStatePolicy) and loaded.delay == 1
    assert loaded.inner.interface.action_delay_steps == 0
    env = make_env("delay_10ms", max_episode_steps=40)
    interface = EnvInterface.from_env(env)
    expert = HeuristicPolicy(interface)
    shadow = EstimatedStatePolicy(HeuristicPolicy(EstimatedStatePolicy.undelayed(interface)), interface)
    obs, _ = env.reset(seed=cfg.seed)
    raw, seen = [], []
    for _ in range(40):
        raw.append(obs)
        seen.append(shadow.observation_for_inner(obs))
        action = expert(obs)
        shadow.record_sent(action)
        obs, *_ = env.step(action)
    stored = res.data.obs[res.data.episode == 0]  # round 0: the expert's episode, seen through the estimator
    n = len(stored)  # it falls at the end (the heuristic under 10 ms of latency)
    assert n >= 38
    np.testing.assert_array_equal(stored, np.array(seen[:n]))
    raw = np.array(raw)
    # the prediction: the observation two steps later (the median row; contacts and motor limits aside)
    assert np.median(np.abs(stored[5:n - 2, :13] - raw[7:n, :13]).max(axis=1)) < 2e-3
    assert np.median(np.abs(stored[5:n - 2, :13] - raw[5:n - 2, :13]).max(axis=1)) > 0.1
    with pytest.raises(ValueError, match="action_queue"):
        DAggerConfig(estimator=True, bc=BCConfig(action_queue=2))
    with pytest.raises(TypeError, match="estimator"):
        DAggerConfig(estimator=1)


def test_cli_condition_errors(capsys):
    from hsddp_gym.cli import main

    for argv, msg in (
            (["dataset", "--condition", "bogus", "--out", "x"], "--condition: bogus (allowed: default, "),
            (["dataset", "--condition", "speed_2.0", "--target-speed", "1", "--out", "x"],
             "--target-speed: given with --condition speed_2.0"),
            (["train", "--algo", "bc", "--dataset", "x", "--condition", "push", "--out", "y"],
             "--condition: given with --algo bc"),
            (["dataset", "--env", "hsddp_gym/Backflip-v0", "--condition", "speed_0.5", "--out", "x"],
             "--condition: condition 'speed_0.5' does not apply to hsddp_gym/Backflip-v0: the task fixes"),
            (["train", "--algo", "dagger", "--env", "hsddp_gym/GapJump-v0", "--condition", "push", "speed_2.0",
              "--out", "y"], "--condition: condition 'speed_2.0' does not apply to hsddp_gym/GapJump-v0"),
            (["train", "--algo", "bc", "--dataset", "x", "--workers", "2", "--out", "y"],
             "--workers: given with --algo bc"),
            (["train", "--algo", "ppo", "--steps", "8", "--condition", "push", "push_x3", "--out", "y"],
             "--condition: 2 names with --algo ppo"),
            (["train", "--algo", "ppo", "--steps", "8", "--vector-env", "--condition", "delay_5ms", "--out", "y"],
             "--condition: delay_5ms (observation noise or latency) with --vector-env")):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's own errors
            code = exc.code
        assert code == 2
        assert msg in capsys.readouterr().err


def test_imitation_robustness_experiment_smoke(tmp_path, experiment):
    """``experiments/imitation_robustness.py`` end to end at a tiny size: datasets (one under the perturbation
    cycle, one at several speeds), learners, the table and the goal check; a rerun reuses everything, other
    settings are refused."""
    pytest.importorskip("torch")
    script = experiment("imitation_robustness")
    out = tmp_path / "run"
    argv = ["--out", str(out), "--demos", "1", "--few", "1", "--perturbed-demos", "2", "--speed-demos", "1",
            "--dagger-rounds", "1", "--dagger-episodes", "1", "--epochs", "1", "--seeds", "1", "--max-steps", "8",
            "--learners", "bc", "dagger_perturbed_queue", "bc_speed", "--conditions", "default", "speed_2.0",
            "--quiet"]
    assert script.main(argv) == 0
    res = json.loads((out / "imitation_robustness.json").read_text())
    assert set(res["results"]) == {"bc", "dagger_perturbed_queue", "bc_speed"}
    assert res["learners"]["dagger_perturbed_queue"]["config"]["bc"]["action_queue"] == script.QUEUE_SLOTS
    assert res["datasets"]["ds_perturbed"]["conditions"] == list(script.TRAIN_PERTURBATIONS)
    meta = json.loads((out / "ds_speeds" / "metadata.json").read_text())
    assert meta["episode_target_speeds"] == [0.5, 1.0, 1.5, 2.0]
    for label, cells in res["results"].items():
        assert cells["speed_2.0"]["target_speed"] == 2.0 and cells["default"]["episodes"] == 1
        assert res["goals"][label]["falls_beyond_mpc_plus_1"] == {}  # 8 steps: nobody falls
    table = (out / "imitation_robustness.md").read_text()
    assert ("| condition | mpc (ref.) | heuristic (ref.) | heuristic+est (ref.) | bc | dagger_perturbed_queue | "
            "bc_speed |") in table
    assert "* **bc_speed**: falls met; speed " in table
    assert script.main(argv) == 0  # reuses the datasets and the learners
    # a second training seed: its own learners (NAME@seed1), each learner's falls over the seeds, and with --ensemble
    # the seeds' mean action (NAME@ens)
    with pytest.raises(SystemExit):
        script.main(argv + ["--ensemble"])  # one training seed: nothing to average
    assert script.main(argv + ["--train-seeds", "0", "1", "--ensemble"]) == 0
    res = json.loads((out / "imitation_robustness.json").read_text())
    learners = ("bc", "dagger_perturbed_queue", "bc_speed")
    assert set(res["results"]) == {*learners, *(f"{n}@seed1" for n in learners), *(f"{n}@ens" for n in learners)}
    assert set(res["over_seeds"]) == set(learners)  # an ensemble is no training seed
    assert res["learners"]["bc@seed1"]["training_seed"] == 1
    assert (out / "learners" / "bc@seed1" / "policy.npz").exists()
    cells = res["over_seeds"]["bc"]["cells"]
    assert cells["default"]["falls"] == [res["results"]["bc"]["default"]["falls"],
                                         res["results"]["bc@seed1"]["default"]["falls"]]
    assert "Over training seeds" in (out / "imitation_robustness.md").read_text()
    # behind the estimator: a learner trained there (evaluated there only) and --estimated twins of the others
    est = [a for a in argv if a not in ("dagger_perturbed_queue", "bc_speed")]
    est[est.index("bc") + 1:est.index("bc") + 1] = ["dagger_speed_est"]
    assert script.main(est + ["--estimated"]) == 0
    res = json.loads((out / "imitation_robustness.json").read_text())
    assert set(res["results"]) == {"bc", "bc+est", "dagger_speed_est"}
    assert res["learners"]["dagger_speed_est"]["config"]["estimator"] is True
    assert res["learners"]["bc+est"]["estimator"] and not res["learners"]["bc"]["estimator"]
    # weighted rollout conditions: a condition named twice gets twice the rollouts (other settings: --overwrite)
    weighted = est + ["--dagger-conditions", "push", "push", "speed_2.0"]
    with pytest.raises(SystemExit):
        script.main(weighted)
    assert script.main(weighted + ["--overwrite"]) == 0
    summary = json.loads((out / "learners" / "dagger_speed_est" / "summary.json").read_text())
    assert summary["conditions"] == ["push", "push", "speed_2.0"] and summary["config"]["episodes_per_round"] == 3
    with pytest.raises(SystemExit):
        script.main(est + ["--dagger-conditions", "sideways"])
    with pytest.raises(SystemExit):
        script.main(argv + ["--train-seeds", "1", "1"])
    with pytest.raises(SystemExit):
        script.main([a if a != "8" else "9" for a in argv])

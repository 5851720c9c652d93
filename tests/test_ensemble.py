"""The mean-action ensemble of learners (:mod:`hsddp_gym.learning.ensemble`) and its use in the robustness benchmark."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hsddp_gym.envs.perturbations import make_env
from hsddp_gym.learning.bc import BCConfig, MLPPolicy
from hsddp_gym.learning.ensemble import EnsemblePolicy, load_mlp_ensemble
from hsddp_gym.planners.policies.base import EnvInterface
from hsddp_gym.planners.policies.estimated_state import EstimatedStatePolicy
from hsddp_gym.planners.policies.heuristic import HeuristicPolicy


def random_mlp(interface: EnvInterface, seed: int, features: str = "gait_clock", estimator: bool = False) -> MLPPolicy:
    """A small MLP with random weights (gait-clock features: a member with its own memory)."""
    rng = np.random.default_rng(seed)
    n_in = interface.layout.size + (7 if features == "gait_clock" else 0)
    weights = [(rng.normal(0, 0.3, (16, n_in)), rng.normal(0, 0.1, 16)),
               (rng.normal(0, 0.3, (4, 16)), rng.normal(0, 0.1, 4))]
    return MLPPolicy(interface, weights=weights, obs_mean=np.zeros(n_in), obs_std=np.ones(n_in),
                     config=BCConfig(hidden=(16,), features=features), info={"estimator": estimator})


def observations(n: int, seed: int = 0) -> list[np.ndarray]:
    """``n`` observations of a heuristic episode (real gait, contact changes for the members' clocks)."""
    env = make_env("default")
    policy = HeuristicPolicy.from_env(env)
    obs, _ = env.reset(seed=seed)
    out = []
    for _ in range(n):
        out.append(obs)
        obs, _, terminated, _, _ = env.step(policy(obs))
        assert not terminated
    env.close()
    return out


def test_the_ensemble_acts_with_the_mean_of_its_members_and_one_member_exactly_as_it():
    interface = EnvInterface()
    members = [random_mlp(interface, s) for s in (1, 2, 3)]
    twins = [m.with_interface(interface) for m in members]  # the same networks, memories of their own
    ensemble = EnsemblePolicy(members)
    single = EnsemblePolicy([random_mlp(interface, 1)])
    alone = random_mlp(interface, 1)
    ensemble.reset()
    for obs in observations(120):
        expected = np.mean([np.asarray(t.act(obs), dtype=np.float64) for t in twins], axis=0).astype(np.float32)
        a = ensemble.act(obs)
        assert a.dtype == np.float32 and a.shape == (4,)
        np.testing.assert_allclose(a, expected, rtol=0, atol=1e-7)
        np.testing.assert_array_equal(single.act(obs), alone.act(obs))
    # the members really differ (the mean is not one of them)
    acts = [m.with_interface(interface).act(observations(1)[0]) for m in members]
    assert not np.allclose(acts[0], acts[1])


def test_spawned_ensembles_keep_their_own_member_memories():
    interface = EnvInterface()
    ensemble = EnsemblePolicy([random_mlp(interface, s) for s in (1, 2)])
    twin = ensemble.spawn()
    assert all(a is not b for a, b in zip(twin.members, ensemble.members))
    assert all(a.clock is not b.clock for a, b in zip(twin.members, ensemble.members))
    obs = observations(40)
    for o in obs:
        ensemble.act(o)
    fresh = EnsemblePolicy([random_mlp(interface, s) for s in (1, 2)])
    np.testing.assert_array_equal(twin.act(obs[0]), fresh.act(obs[0]))  # untouched by the other copy's episode


def test_bad_members_are_refused_by_name():
    interface = EnvInterface()
    with pytest.raises(ValueError, match="members"):
        EnsemblePolicy([])
    with pytest.raises(TypeError, match=r"members\[1\]"):
        EnsemblePolicy([random_mlp(interface, 1), "policy"])
    with pytest.raises(ValueError, match=r"members\[1\]"):
        EnsemblePolicy([random_mlp(interface, 1), random_mlp(EnvInterface(target_speed=2.0), 2)])


def test_loaded_ensembles_act_behind_one_estimator_when_their_members_were_trained_behind_it(tmp_path):
    interface = EnvInterface()
    plain = [random_mlp(interface, s).save(tmp_path / f"p{s}" / "policy.npz").parent for s in (1, 2)]
    behind = [random_mlp(interface, s, estimator=True).save(tmp_path / f"e{s}" / "policy.npz").parent
              for s in (1, 2)]
    ens = load_mlp_ensemble(plain, interface)
    assert isinstance(ens, EnsemblePolicy) and len(ens.members) == 2
    wrapped = load_mlp_ensemble([str(d) for d in behind], interface)
    assert isinstance(wrapped, EstimatedStatePolicy) and isinstance(wrapped.inner, EnsemblePolicy)
    # with exact observations and no delay the estimator passes the observation through: the same actions
    for obs in observations(30):
        np.testing.assert_array_equal(wrapped.act(obs), ens.act(obs))
    with pytest.raises(ValueError, match="mixes"):
        load_mlp_ensemble([plain[0], behind[0]], interface)
    with pytest.raises(FileNotFoundError, match=r"run_dirs\[1\]"):
        load_mlp_ensemble([plain[0], tmp_path / "none"], interface)
    for bad in ([], str(plain[0])):
        with pytest.raises(ValueError, match="run_dirs"):
            load_mlp_ensemble(bad, interface)


def test_the_robustness_benchmark_runs_an_ensemble_of_comma_separated_runs(tmp_path, experiment):
    rob = experiment("robustness")
    interface = EnvInterface()
    dirs = [str(random_mlp(interface, s, features="obs").save(tmp_path / f"r{s}" / "policy.npz").parent)
            for s in (1, 2)]
    out = tmp_path / "out"
    assert rob.main(["--out", str(out), "--policies", "--learned", f"bc@ens={','.join(dirs)}", "--learned",
                     f"bc@one={dirs[0]}", "--estimated", "bc@ens", "--conditions", "default", "--seeds", "1",
                     "--max-steps", "5", "--quiet"]) == 0
    rec = json.loads((out / "robustness.json").read_text())
    assert rec["policies"]["bc@ens"] == {"kind": "bc", "dirs": dirs}
    assert set(rec["results"]) == {"bc@ens", "bc@one", "bc@ens+est"}
    env = make_env("default")
    assert isinstance(rob.benchmark_policy({"kind": "bc", "dirs": dirs}, env), EnsemblePolicy)
    assert isinstance(rob.benchmark_policy({"kind": "bc", "dirs": dirs, "estimator": True}, env), EstimatedStatePolicy)
    env.close()
    with pytest.raises(SystemExit):  # only bc/dagger learners average
        rob.main(["--out", str(out), "--policies", "--learned", f"ppo@ens={','.join(dirs)}", "--quiet"])
    # one missing member skips the ensemble, with a note
    assert rob.main(["--out", str(out), "--policies", "heuristic", "--learned", f"bc@ens={dirs[0]},{tmp_path}/none",
                     "--conditions", "default", "--seeds", "1", "--max-steps", "5", "--quiet"]) == 0
    assert set(json.loads((out / "robustness.json").read_text())["skipped"]) == {"bc@ens"}


def test_every_loader_of_a_learner_trained_behind_the_estimator_puts_it_behind_one(tmp_path, experiment):
    """One loader (load_mlp_learner) for the CLI's policies, the robustness benchmark and the policy comparison: a
    single run trained behind the MPC's perception acts behind it everywhere (the comparison used to load it bare)."""
    import json

    from hsddp_gym.learning.ensemble import load_mlp_learner
    from hsddp_gym.workflows import load_policy

    interface = EnvInterface()
    plain = random_mlp(interface, 1).save(tmp_path / "plain" / "policy.npz").parent
    behind = random_mlp(interface, 2, estimator=True).save(tmp_path / "behind" / "policy.npz").parent
    for d in (plain, behind):
        (d / "summary.json").write_text(json.dumps({"algo": "dagger", "expert_labels": 10,
                                                    "expert": {"name": "heuristic"}}))
    assert type(load_mlp_learner(plain, interface)) is MLPPolicy
    single = load_mlp_learner(str(behind), interface)
    assert isinstance(single, EstimatedStatePolicy) and type(single.inner) is MLPPolicy
    env = make_env("default")
    compared, info = experiment("compare_policies").build("dagger", behind)
    assert isinstance(compared, EstimatedStatePolicy) and info["samples"].startswith("10 expert labels")
    assert type(experiment("compare_policies").build("dagger", plain)[0]) is MLPPolicy
    assert isinstance(load_policy(f"dagger:{behind}", env), EstimatedStatePolicy)
    assert isinstance(experiment("robustness").benchmark_policy({"kind": "dagger", "dir": str(behind)}, env),
                      EstimatedStatePolicy)
    bare = MLPPolicy.load(behind / "policy.npz", interface)
    for obs in observations(20):  # exact observations, no delay: the estimator passes them through
        np.testing.assert_array_equal(single.act(obs), bare.act(obs))
    with pytest.raises(FileNotFoundError, match="run_dirs: no"):
        load_mlp_learner(tmp_path / "none", interface)
    for bad in ([], None, 3):
        with pytest.raises(ValueError, match="run_dirs"):
            load_mlp_learner(bad, interface)

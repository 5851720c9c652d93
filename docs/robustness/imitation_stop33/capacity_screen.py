"""Record of stop 33's capacity screen: another network trained on the aggregate labels of a stop-32 DAgger run.

Usage (from the project root, after stop 32's ``python experiments/imitation_robustness.py --out
runs/imitation_stop32_est2 --workers 1 --train-seeds 0 1 2 --learners dagger_speed_est --dagger-rounds 4
--dagger-episodes 18 --quiet``)::

    python docs/robustness/imitation_stop33/capacity_screen.py SEED HIDDEN TAG    # e.g. 1 512,512 w512

writes ``runs/bignet/sSEED_TAG/policy.npz``: BC with the run's last-round config (``hidden`` replaced) on the run's
``dagger_data.npz``. Stop 32's files lack the pairs' target speeds (kept since stop 33,
:data:`hsddp_gym.learning.dagger.DATA_OPTIONAL`); they are rebuilt here from the rollout order: the 24 initial
demonstrations from ``ds_speeds``, then rollout ``j`` of each round ran in condition ``j % 12`` of
``DAGGER_SPEED_CONDITIONS``. With ``HIDDEN`` 256,256 the retrained policy is bit-identical to the run's own
(``identical_to_stop32`` in its ``summary.json``), which checks the rebuilt speeds.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from hsddp_gym.datasets.collection import make_env
from hsddp_gym.envs.perturbations import CONDITIONS
from hsddp_gym.learning.bc import BCConfig, MLPPolicy, train_bc
from hsddp_gym.learning.dagger import load_dagger_data
from hsddp_gym.learning.demonstrations import load_demonstrations
from hsddp_gym.learning.features import make_gait_clock
from hsddp_gym.planners.policies.base import EnvInterface

RUN = Path("runs/imitation_stop32_est2")
# stop 32's rollout cycle, frozen here (not imported from experiments/imitation_robustness.py, whose default may change)
DAGGER_SPEED_CONDITIONS = ("default", "reset_noise_x4", "obs_noise", "delay_5ms", "delay_10ms", "push",
                           "friction_0.4", "mass_+15", "mass_-15", "speed_0.5", "speed_1.5", "speed_2.0")
ROLLOUTS_PER_ROUND = 24


def main(seed: int, hidden: tuple, tag: str) -> None:
    src = RUN / "learners" / ("dagger_speed_est" + ("" if seed == 0 else f"@seed{seed}"))
    summary = json.loads((src / "summary.json").read_text())
    data = load_dagger_data(src)
    initial = load_demonstrations(RUN / "ds_speeds", fmt="npz")
    speed = np.empty(len(data))
    for e in range(data.n_episodes):
        rows = data.episode == e
        if e < initial.n_episodes:
            speed[rows] = initial.target_speed[initial.episode == e][0]
        else:
            c = DAGGER_SPEED_CONDITIONS[((e - initial.n_episodes) % ROLLOUTS_PER_ROUND) % len(DAGGER_SPEED_CONDITIONS)]
            speed[rows] = CONDITIONS[c].env_kwargs.get("target_speed", 1.0)
    data = dataclasses.replace(data, target_speed=speed)
    config = BCConfig(**{**summary["config"]["bc"], "hidden": hidden})
    config = dataclasses.replace(config, seed=config.seed + summary["config"]["rounds"])  # the last round's seed
    env = make_env({}, None)
    interface = EnvInterface.from_env(env)
    env.close()
    t0 = time.perf_counter()
    policy, history = train_bc(data, config, interface, clock=make_gait_clock(interface))
    policy.info.update(expert_labels=len(data), dagger_rounds=summary["config"]["rounds"], estimator=True)
    out = Path("runs/bignet") / f"s{seed}_{tag}"
    out.mkdir(parents=True, exist_ok=True)
    policy.save(out / "policy.npz")
    own = MLPPolicy.load(src / "policy.npz")
    same = len(own.weights) == len(policy.weights) and all(
        np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) for a, b in zip(own.weights, policy.weights))
    (out / "summary.json").write_text(json.dumps({
        "algo": "dagger", "hidden": list(hidden), "wall_time_s": time.perf_counter() - t0,
        "final_loss": history["loss"][-1], "identical_to_stop32": same, "labels": len(data)}))
    print(out, "loss", history["loss"][-1], "identical", same, flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]), tuple(int(h) for h in sys.argv[2].split(",")), sys.argv[3])

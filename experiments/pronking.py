"""The pronking task (``hsddp_gym/Pronking-v0``): the expert, BC, DAgger, SAC and PPO on unseen seeds, and the expert
(with ``--mujoco`` every learner too) in the MuJoCo twin.

Each policy plays ``--episodes`` episodes seeded ``--seed, --seed + 1, ...`` (default 9500-9519, seeds no dataset
uses) of the default task (1 m/s, 1000 steps, reset noise 0.01); per episode the return, a fall, the mean forward
speed, the fraction of control steps with matching contact flags and the task's success
(:func:`hsddp_gym.envs.pronking.pronking_success`); with ``--conditions``, each policy's successes on the same seeds
under those conditions of the perturbation suite.

    python experiments/pronking.py --mujoco --conditions push obs_noise --bc runs/pronk_bc_s0 runs/pronk_bc_s1 \\
        --dagger runs/pronk_dagger_s0 runs/pronk_dagger_s1 --sac runs/pronk_sac120_s0 --ppo runs/pronk_ppo120_s0 \\
        --record results/tasks/pronking.json --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."

``--bc`` / ``--dagger`` take ``hsddp-gym train --algo bc|dagger --out DIR`` runs, ``--sac`` / ``--ppo`` take
``hsddp-gym train --algo sac|ppo --env hsddp_gym/Pronking-v0 --out DIR`` runs, each evaluated with its final weights
and its best checkpoint (the best training-time evaluation, on the run's own seeds), both with the mean action.
"""

from __future__ import annotations

from hsddp_gym.benchmarks.tasks import task_evaluation_main


def main(argv=None) -> int:
    return task_evaluation_main(argv, __doc__, task="pronking", record_settings={"target_speed": 1.0},
                                rounds_word="round", env_checked=("dagger",))


if __name__ == "__main__":
    raise SystemExit(main())

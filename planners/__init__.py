"""Installed as ``hsddp_gym.planners``: the optimizer (:mod:`hsddp_gym.planners.optimizer`), the policies built
on it (:mod:`hsddp_gym.planners.policies`) and the paper's planning tasks (:mod:`hsddp_gym.planners.tasks`)."""

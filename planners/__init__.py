"""Installed as ``hsddp_gym.planners``: the optimizer ([`hsddp_gym.planners.optimizer`][hsddp_gym.planners.optimizer]),
the policies built on it ([`hsddp_gym.planners.policies`][hsddp_gym.planners.policies]) and the paper's planning tasks
([`hsddp_gym.planners.tasks`][hsddp_gym.planners.tasks])."""

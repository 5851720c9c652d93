"""The tasks' HS-DDP plans and plan-tracking experts, read from the task registry
([`hsddp_gym.registry`][hsddp_gym.registry]).

One cache for every task: a plan is solved once per process and per task and values of its env-read arguments
(``Task.plan_inputs``: plan knots per control period, target speed). The one place an expert is built.
"""

from __future__ import annotations

from hsddp_gym.registry import Task, resolve, task_of_env

_PLANS: dict = {}
_KEEP = ("status", "converged", "al_iterations", "ddp_iterations", "switching_violation", "cost", "avg_forward_speed",
         "solve_time_s")


def control_hold(dt: float) -> int:
    """Plan knots (1 ms) per control period ``dt`` [s]: the ``hold`` of the held-input plans."""
    return max(1, int(float(dt) / 1e-3 + 0.5))


def env_plan_inputs(task: Task, env) -> dict:
    """The values of ``task.plan_inputs`` read from ``env`` (wrapped or not): ``hold`` from its control period,
    ``speed`` its target speed."""
    u = getattr(env, "unwrapped", env)
    values = {"hold": lambda: control_hold(u.dt), "speed": lambda: float(u.target_speed)}
    return {name: values[name]() for name in task.plan_inputs}


def solve_task_plan(task: Task, **inputs):
    """The result of ``task``'s plan function (a [`PlanResult`][hsddp_gym.planners.tasks.PlanResult] or a
    [`Solution`][hsddp_gym.planners.optimizer.solution.Solution]) for the values ``inputs`` of ``task.plan_inputs``,
    solved once per process and per ``(task, inputs)``."""
    if task.plan is None:
        raise ValueError(f"task {task.name!r} has no plan (its expert is the {task.dataset_expert!r} policy)")
    if set(inputs) != set(task.plan_inputs):
        raise ValueError(f"the plan of {task.name!r} takes {sorted(task.plan_inputs)} from the env, got "
                         f"{sorted(inputs)}")
    key = (task.name, *sorted((k, float(v) if k == "speed" else int(v)) for k, v in inputs.items()))
    if key not in _PLANS:
        _PLANS[key] = resolve(task.plan)(**task.plan_kwargs, **dict(key[1:]))
    return _PLANS[key]


def task_plan(task: Task, env=None, **inputs):
    """``task``'s plan (a [`Solution`][hsddp_gym.planners.optimizer.solution.Solution]) for ``env`` (its control period
    and target speed, when the plan reads them) or for the given ``inputs`` (cached,
    [`solve_task_plan`][solve_task_plan])."""
    if env is not None:
        inputs = {**env_plan_inputs(task, env), **inputs}
    result = solve_task_plan(task, **inputs)
    return getattr(result, "solution", result)


def plan_summary(task: Task, **inputs) -> dict:
    """What a dataset records of ``task``'s plan for ``inputs``: status, convergence, iterations, switching
    violation, cost, solve time (and, for a [`PlanResult`][hsddp_gym.planners.tasks.PlanResult], its forward speed; for
    a held plan its ``hold``)."""
    result = solve_task_plan(task, **inputs)
    if hasattr(result, "summary"):
        return {k: result.summary[k] for k in _KEEP if k in result.summary}
    sol = result
    return {"status": sol.status, "converged": bool(sol.converged), "al_iterations": int(sol.al_iterations),
            "ddp_iterations": int(sol.ddp_iterations), "switching_violation": float(sol.switching_violation),
            "cost": float(sol.cost), "solve_time_s": float(sol.solve_time), "hold": int(inputs["hold"])}


def make_expert(env, solution=None, task: Task | None = None):
    """The plan-tracking expert of ``env``'s task (``task``: that task, default [`task_of_env`][task_of_env]) tracking
    ``solution`` (None: the task's plan for the env, [`task_plan`][task_plan]); its ``reset_options`` attribute holds
    the reset options its episodes need (``{"state": plan.X[0]}`` when the expert starts at its plan's first state, else
    None)."""
    task = task if task is not None else task_of_env(env)
    if task.expert is None:
        raise ValueError(f"task {task.name!r} has no plan-tracking expert: its expert is the "
                         f"{task.dataset_expert!r} policy")
    solution = solution if solution is not None else task_plan(task, env)
    from hsddp_gym.planners.policies.base import EnvInterface

    expert = resolve(task.expert)(EnvInterface.from_env(env), solution, **task.expert_kwargs)
    expert.reset_options = {"state": solution.X[0].copy()} if task.expert_starts_at_plan else None
    return expert

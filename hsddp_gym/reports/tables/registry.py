"""The register of the results tables: [`TABLES`][TABLES] maps a table id (the ``ID`` of ``<!-- results: ID -->``) to
its renderer, and [`render`][render] draws one."""

from __future__ import annotations

from collections.abc import Callable

from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.ablations import (
    robustness_rule_ablations,
    robustness_rule_ablations_push_laws,
    robustness_rule_ablations_pushes,
)
from hsddp_gym.reports.tables.learned import learning_imitation, policies_protocol
from hsddp_gym.reports.tables.paper import paper_sto_periodic, paper_sto_variants, paper_task1
from hsddp_gym.reports.tables.physics import env_physics
from hsddp_gym.reports.tables.robustness import (
    TASK_MPC_TASKS,
    robustness_contact_models,
    robustness_generality,
    robustness_generality_summary,
    robustness_pushes,
    robustness_simulators,
    robustness_suite,
    robustness_summary,
    robustness_task_mpc_summary,
    robustness_tasks_backflip,
    robustness_tasks_jumps,
    robustness_tasks_pronking,
    robustness_tasks_rl_backflip,
    robustness_tasks_rl_jumps,
    robustness_tasks_transitions,
    task_mpc_table,
)
from hsddp_gym.reports.tables.speed import (
    speed_dynamics,
    speed_env,
    speed_mpc,
    speed_solver,
    speed_solver_horizons,
    speed_summary,
    speed_task_mpc,
    speed_vector_env,
    speed_vector_env_tasks,
)
from hsddp_gym.reports.tables.tasks import (
    motions_summary,
    tasks_backflip,
    tasks_bound_pronk_bound,
    tasks_bound_to_stop,
    tasks_box_jump,
    tasks_gap_jump,
    tasks_pronking,
    tasks_stand_to_bound,
    tasks_summary,
    tasks_terrain,
)

TABLES: dict[str, Callable[[Store], str]] = {
    "paper/task1": paper_task1,
    "paper/sto_variants": paper_sto_variants,
    "paper/sto_periodic": paper_sto_periodic,
    "env/physics": env_physics,
    "speed/env": speed_env,
    "speed/vector_env": speed_vector_env,
    "speed/vector_env_tasks": speed_vector_env_tasks,
    "speed/dynamics": speed_dynamics,
    "speed/solver": speed_solver,
    "speed/solver_horizons": speed_solver_horizons,
    "speed/mpc": speed_mpc,
    "speed/task_mpc": speed_task_mpc,
    "speed/summary": speed_summary,
    "robustness/suite": robustness_suite,
    "robustness/summary": robustness_summary,
    "robustness/simulators": robustness_simulators,
    "robustness/contact_models": robustness_contact_models,
    "policies/protocol": policies_protocol,
    "learning/imitation": learning_imitation,
    "motions/summary": motions_summary,
    "tasks/pronking": tasks_pronking,
    "tasks/backflip": tasks_backflip,
    "tasks/terrain": tasks_terrain,
    "tasks/gap_jump": tasks_gap_jump,
    "tasks/box_jump": tasks_box_jump,
    "tasks/stand_to_bound": tasks_stand_to_bound,
    "tasks/bound_pronk_bound": tasks_bound_pronk_bound,
    "tasks/bound_to_stop": tasks_bound_to_stop,
    "tasks/summary": tasks_summary,
    "robustness/generality": robustness_generality,
    "robustness/generality_summary": robustness_generality_summary,
    "robustness/pushes": robustness_pushes,
    "robustness/rule_ablations": robustness_rule_ablations,
    "robustness/rule_ablations_pushes": robustness_rule_ablations_pushes,
    "robustness/rule_ablations_push_laws": robustness_rule_ablations_push_laws,
    "robustness/tasks_pronking": robustness_tasks_pronking,
    "robustness/tasks_backflip": robustness_tasks_backflip,
    "robustness/tasks_jumps": robustness_tasks_jumps,
    "robustness/tasks_transitions": robustness_tasks_transitions,
    "robustness/tasks_rl_backflip": robustness_tasks_rl_backflip,
    "robustness/tasks_rl_jumps": robustness_tasks_rl_jumps,
    "robustness/task_mpc_summary": robustness_task_mpc_summary,
    **{f"robustness/task_mpc_{task}": task_mpc_table(task) for task in TASK_MPC_TASKS},
}
"""``{table id: renderer}``."""


def render(store: Store, table_id: str) -> str:
    """The Markdown of table ``table_id``.

    Raises:
        KeyError: an unknown table id (naming the known ones).
    """
    if table_id not in TABLES:
        raise KeyError(f"unknown results table {table_id!r} (known: {', '.join(sorted(TABLES))})")
    return TABLES[table_id](store)

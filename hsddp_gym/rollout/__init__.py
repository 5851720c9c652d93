"""Playing policies in the task envs: the policy factory, the tasks' plans and experts, the episode loop and the
tasks' per-episode measures.

The layer below datasets and learning (it reads the task registry, [`hsddp_gym.registry`][hsddp_gym.registry]; learned
policies are loaded through ``"module:attr"`` strings,
[`hsddp_gym.rollout.policies.LEARNED_LOADERS`][hsddp_gym.rollout.policies.LEARNED_LOADERS]). """

from hsddp_gym.util.lazy import lazy_exports

_EXPORTS = {  # module: the public names it defines
    "episodes": ("EpisodeResult", "FrameRecorder", "Returns", "reset_options_of", "run_episode", "summarize"),
    "measures": ("Measures", "TaskEpisodes"),
    "plans": ("control_hold", "make_expert", "plan_summary", "solve_task_plan", "task_plan"),
    "policies": ("LEARNED_POLICIES", "POLICIES", "PolicySpec", "load_plan", "make_policy", "parse_policy_spec",
                 "required_modules"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)

"""HS-DDP model-predictive control: the agent that drives the estimators, the planner and the feedback law.

As in MuJoCo MPC, the planner optimizes and the policy is queried at the control rate from the latest plan; the
loop that drives both is separate from each. Every control step [`MPCPolicy.act`][MPCPolicy.act]

1. estimates the state from the observation ([`StateEstimator`][hsddp_gym.planners.policies.mpc.state.StateEstimator]:
   sensor bias, action delay, model-based filter) and predicts it over the action delay; 2. advances the contact phase
([`ContactScheduleEstimator`][hsddp_gym.planners.policies.mpc.schedule.ContactScheduleEstimator]) from
   the estimate and the contact flags, and over the delay with the predicted contacts;
3. re-plans from the predicted state every ``replan.period`` (at once when the phase moved against the cycle):
   the schedule estimator's schedule, the speed reference's speed
   ([`SpeedReference`][hsddp_gym.planners.policies.mpc.speed.SpeedReference]), the previous plan shifted as the warm
   start ([`MPCPlanner`][hsddp_gym.planners.policies.mpc.planner.MPCPlanner]);
4. acts with the latest plan's feedback law ([`FeedbackLaw`][hsddp_gym.planners.policies.mpc.law.FeedbackLaw]); when its
   feedback term alone would ask a motor for more than ``replan.feedback_threshold`` of the torque limit, the state
   is too far from the plan for its linearization and the agent re-plans from it at once (a feedback re-plan).

A failed re-plan never ends the episode: the previous plan's feedback law keeps acting and the failure is counted
in `MPCPolicy.stats`. Only while no plan exists yet does the schedule-driven heuristic act instead (a start-up
controller).
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, Mode
from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController, HeuristicGains
from hsddp_gym.planners.policies.mpc.ground import GroundModel
from hsddp_gym.planners.policies.mpc.law import FeedbackLaw, feedback_torques
from hsddp_gym.planners.policies.mpc.options import MPCOptions
from hsddp_gym.planners.policies.mpc.planner import MPCPlanner
from hsddp_gym.planners.policies.mpc.schedule import ContactScheduleEstimator
from hsddp_gym.planners.policies.mpc.speed import SpeedReference
from hsddp_gym.planners.policies.mpc.state import StateEstimator


class MPCPolicy(Policy):
    """HS-DDP MPC acting from observations (see the module docstring).

    Args:
        interface: the env's public settings (``MPCPolicy.from_env(env)``).
        options: [`MPCOptions`][hsddp_gym.planners.policies.mpc.options.MPCOptions].
        terrain: the ground, given as privileged information (None, the default: the MPC plans for flat ground
            where the feet put it): a [`Terrain`][hsddp_gym.core.terrain.Terrain], or a function of no argument
            returning the current episode's, called at every `reset` (e.g.
            [`env_terrain`][hsddp_gym.planners.policies.mpc.ground.env_terrain] of an env whose terrain is drawn at its
            reset: reset the env first). With a terrain the MPC works in the world frame
            ([`hsddp_gym.planners.policies.mpc.ground`][hsddp_gym.planners.policies.mpc.ground]), and without the trunk
            x in the observation it integrates the measured forward speed for it.

    Attributes:
        estimator: the state estimator. schedule: the contact-schedule estimator. planner: the planner.
        law: the feedback law of the plan acted on. speed: the plans' speed reference.
        last_estimate: the filtered state (14,) of the last observation. last_prediction: the state (14,) the last
            action was computed for (the estimate predicted over the action delay).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), options: MPCOptions = MPCOptions(),
                 terrain=None) -> None:
        super().__init__(interface)
        if not isinstance(options, MPCOptions):
            raise TypeError(f"options must be an MPCOptions, got {type(options).__name__}")
        self.options = options
        self.terrain_source = terrain
        """The ``terrain`` argument (None, a Terrain or a function returning one)."""
        self.durations = options.plan.durations if options.plan.durations is not None else PAPER_BOUNDING_DURATIONS
        self._build()
        self.reset()

    def _build(self) -> None:
        """The components, each with models of its own (also for a spawned copy)."""
        o, i = self.options, self.interface
        self.planner = MPCPlanner(o.plan, o.replan, i.torque_limit, i.target_speed, None)
        robot = self.planner.dynamics.robot
        self.ground = GroundModel(self.terrain_source, robot.params.hip_offset)
        self.planner.ground = self.ground
        self.estimator = StateEstimator(i, o.estimator, robot)
        self.schedule = ContactScheduleEstimator(self.durations, i.control_dt, o.schedule, o.plan, robot, self.ground)
        friction = o.plan.friction if o.plan.friction is not None else robot.params.friction
        self.law = FeedbackLaw(i.torque_limit, o.min_stance_force, friction, self.ground, robot)
        self.speed = SpeedReference(i.target_speed, round(sum(self.durations) / i.control_dt), o.speed)
        self._startup_controller = HeuristicBoundingController(gains=HeuristicGains(speed=i.target_speed),
                                                               height_offset=o.plan.height_offset)
        """Acts while no plan exists yet (the episode's first re-plan failed): the schedule-driven heuristic."""

    def _reset_copy_state(self) -> None:
        self._build()

    def reset(self) -> None:
        self.planner.reset()
        self.estimator.reset(self.ground.reset())
        self.schedule.reset()
        self.speed.reset()
        self.law.plan = None
        self.stats = self.planner.stats
        """``replans``, ``planner_failures``, ``solve_ms`` (list), ``iterations`` (list), ``time_budget_stops``,
        ``restarts``, ``restarts_kept`` ([`MPCPlanner`][hsddp_gym.planners.policies.mpc.planner.MPCPlanner]'s own, the
        same dict), ``delay_changes`` (the delay estimate's moves) and ``feedback_replans`` (feedback re-plans tried)
        since `reset`: one live dict, updated in place."""
        self.stats.update(delay_changes=0, feedback_replans=0)
        self.last_estimate: np.ndarray | None = None
        self.last_prediction: np.ndarray | None = None
        self._since_replan = np.inf

    # ------------------------------------------------------------------ what the components know
    @property
    def last_solution(self):
        """The plan acted on (a [`Solution`][hsddp_gym.planners.optimizer.solution.Solution]; None before the first)."""
        return None if self.law.plan is None else self.law.plan.solution

    @property
    def clock(self):
        """The gait clock of the observed state (the schedule estimator's)."""
        return self.schedule.clock

    @property
    def terrain(self):
        """The terrain of the current episode (None: flat ground)."""
        return self.ground.terrain

    @property
    def announced_delay(self) -> int:
        """The action delay the env announces [control steps] (``EnvInterface.action_delay_steps``)."""
        return self.estimator.announced_delay

    @property
    def action_delay(self) -> int:
        """The action delay compensated for [control steps] (the announced one or its online estimate)."""
        return self.estimator.action_delay

    # ------------------------------------------------------------------ the loop
    def replan(self, x: np.ndarray, feedback: bool = False) -> bool:
        """Plan from the (predicted) state ``x`` (14,) and act on the plan; returns True on success. ``feedback``: a
        re-plan made at once because the feedback law would saturate."""
        schedule = self.schedule.schedule(x)
        plan = self.planner.plan(x, schedule, self.speed.plan_speed(x), self.schedule.plan_height(self.estimator.bias),
                                 self.law.plan, feedback)
        if plan is None:
            return False
        self.law.plan = plan
        return True

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The plan's feedback law at the cursor, re-planning every ``replan.period`` (at once when the schedule
        changed against the cycle or the feedback law would saturate); before the first plan exists, the start-up
        controller."""
        x_obs, mode, _ = self._parse(obs)
        x_est = self.estimator.update(x_obs, mode)
        self.stats["delay_changes"] = self.estimator.delay_changes
        self.speed.observe(float(x_est[NQ]))
        self.last_estimate = x_est
        self.schedule.observe(x_est, mode, self.estimator.bias)
        steps = self.estimator.predict(x_est, mode)
        eff = self.schedule.predict(steps)
        x = steps[-1][0] if steps else x_est
        self.last_prediction = x.copy()
        self.law.sync(eff)
        if self.schedule.resynced:
            self._since_replan = np.inf  # the schedule changed against the cycle: re-plan now
        dt = self.interface.control_dt
        if self._since_replan >= self.options.replan.period - 1e-9:
            self._since_replan = 0.0
            self.speed.update_bias()
            self.replan(x)
        if self.law.plan is None:
            u = self._startup_controller.torque(self.ground.level(x), eff)
        else:
            u, tried = feedback_torques(self.law, x, self.options.replan.feedback_threshold, self._feedback_replan())
            if tried:
                self._since_replan = 0.0
            self.law.advance(dt)
        self.schedule.tick()
        self._since_replan += dt
        self.speed.tick(dt)
        action = self.interface.action_from_torque(u)
        self.estimator.record_sent(action)
        return action

    def _feedback_replan(self):
        """The feedback re-plan ``feedback_torques`` may make now (counted in ``stats``), or None: not in the step of
        a periodic re-plan."""
        if not self._since_replan > 0.0:
            return None

        def replan(x: np.ndarray) -> bool:
            self.stats["feedback_replans"] += 1
            return self.replan(x, feedback=True)
        return replan

    def note_sent_action(self, action) -> None:
        """Tell the MPC that ``action`` (4,) (normalized, as [`act`][act] returns them) was sent to the env in place
        of the one it returned last (a learner's action in a DAgger rollout, the expert's action plus DART noise):
        its state filter and latency compensation then predict with the action the env executes."""
        self.estimator.replace_sent(action)

    def startup_mode(self) -> Mode:
        """The contact mode the start-up controller is fed (the plan clock's)."""
        return self.schedule.plan_clock.mode

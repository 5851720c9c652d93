"""Every results table of the README and the documentation site, rendered from the records of the results store.

[`TABLES`][hsddp_gym.reports.tables.registry.TABLES] maps a table id (the ``ID`` of ``<!-- results: ID -->``) to a
function of the [`Store`][hsddp_gym.reports.store.Store] that returns the table as Markdown, followed by a line naming
the records it comes from and the commands that made them ([`render`][hsddp_gym.reports.tables.registry.render] draws
one). A module per topic:

* [`markdown`][hsddp_gym.reports.tables.markdown]: number formatting, Markdown tables, the provenance line;
* [`paper`][hsddp_gym.reports.tables.paper]: tasks 1 and 2 beside the paper;
* [`physics`][hsddp_gym.reports.tables.physics]: the env's physical claims;
* [`speed`][hsddp_gym.reports.tables.speed]: the env, the dynamics, the solver and the MPC against references;
* [`robustness`][hsddp_gym.reports.tables.robustness]: falls under perturbations, simulators, contact models, pushes;
* [`learned`][hsddp_gym.reports.tables.learned]: the learned policies under one protocol and under the suite;
* [`tasks`][hsddp_gym.reports.tables.tasks]: the planned motions and the tasks beyond bounding;
* [`registry`][hsddp_gym.reports.tables.registry]: table id -> renderer.
"""

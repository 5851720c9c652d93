"""Every results table of the README and the documentation site, rendered from the records of the results store.

:data:`~hsddp_gym.reports.tables.registry.TABLES` maps a table id (the ``ID`` of ``<!-- results: ID -->``) to a function
of the :class:`~hsddp_gym.reports.store.Store` that returns the table as Markdown, followed by a line naming the records
it comes from and the commands that made them (:func:`~hsddp_gym.reports.tables.registry.render` draws one). A module
per topic:

* :mod:`~hsddp_gym.reports.tables.markdown`: number formatting, Markdown tables, the provenance line;
* :mod:`~hsddp_gym.reports.tables.paper`: tasks 1 and 2 beside the paper;
* :mod:`~hsddp_gym.reports.tables.physics`: the env's physical claims;
* :mod:`~hsddp_gym.reports.tables.speed`: the env, the dynamics, the solver and the MPC against references;
* :mod:`~hsddp_gym.reports.tables.robustness`: falls under perturbations, simulators, contact models, pushes;
* :mod:`~hsddp_gym.reports.tables.learned`: the learned policies under one protocol and under the suite;
* :mod:`~hsddp_gym.reports.tables.tasks`: the planned motions and the tasks beyond bounding;
* :mod:`~hsddp_gym.reports.tables.registry`: table id -> renderer.
"""

"""The results store and the tables and figures made from it.

``results/`` (at the top of the repository) holds small JSON records by topic, each with the command that made it
([`hsddp_gym.reports.store`][hsddp_gym.reports.store]). Every results table of the README and the documentation site
sits between ``<!-- results: ID -->`` and ``<!-- /results -->`` and is generated from the records
([`hsddp_gym.reports.tables`][hsddp_gym.reports.tables]), every results figure likewise
([`hsddp_gym.reports.figures`][hsddp_gym.reports.figures])::

    python -m hsddp_gym.reports            # regenerate every table (and, with --figures, every figure)
    python -m hsddp_gym.reports --check    # exit 1 when a published table differs from what the store gives
"""

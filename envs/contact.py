"""The env's contact simulator; it lives in :mod:`hsddp_gym.core.contact` (a model that policies may use too, e.g.
the MPC's latency predictor) and is re-exported here for compatibility."""

from hsddp_gym.core.contact import (  # noqa: F401
    CONTACT_MARGIN,
    PENETRATION_SLOP,
    POSITION_TOLERANCE,
    SEPARATE,
    SLIDE_NEG,
    SLIDE_POS,
    STATE_NAMES,
    STICK,
    ContactSimulator,
    check_motor_speed_limits,
    solve_contact_lcp,
    solve_contact_lcp_lists,
)

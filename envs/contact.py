"""The env's contact simulator; it lives in [`hsddp_gym.core.contact`][hsddp_gym.core.contact] (a model that policies
may use too, e.g. the MPC's latency predictor), its LCP in [`hsddp_gym.core.contact_lcp`][hsddp_gym.core.contact_lcp];
both are re-exported here for compatibility."""

from hsddp_gym.core.contact import (  # noqa: F401
    CONTACT_MARGIN,
    PENETRATION_SLOP,
    POSITION_TOLERANCE,
    ContactSimulator,
    check_motor_speed_limits,
)
from hsddp_gym.core.contact_lcp import (  # noqa: F401
    SEPARATE,
    SLIDE_NEG,
    SLIDE_POS,
    STATE_NAMES,
    STICK,
    solve_contact_lcp,
    solve_contact_lcp_lists,
)

"""The paper's numbers (Kottapalli, AIAA 2000-4305), and the sections that put a reproduction
beside them.
"""

from .comparison import (
    AUTOROTATION,
    PAPER_AUTOROTATION,
    PAPER_PULLUP,
    PAPER_REPLAY,
    PAPER_T1,
    PAPER_TABLE1,
    PULLUP,
    check,
    comparison_markdown,
    database_checks,
    network_checks,
    networks_results,
    paper_figures,
    pullup_replays,
    replay_checks,
)

__all__ = [
    "AUTOROTATION",
    "PAPER_AUTOROTATION",
    "PAPER_PULLUP",
    "PAPER_REPLAY",
    "PAPER_T1",
    "PAPER_TABLE1",
    "PULLUP",
    "check",
    "comparison_markdown",
    "database_checks",
    "network_checks",
    "networks_results",
    "paper_figures",
    "pullup_replays",
    "replay_checks",
]

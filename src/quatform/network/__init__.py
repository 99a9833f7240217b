"""Robot teams on communication networks (formations and planning layer).

What a user checks before flying a decentralised formation: the graph (who hears whom), that
it has a directed spanning tree, its λ₂ and the consensus rate it predicts
(:mod:`.graph`), and that the desired relative poses agree around every cycle
(:mod:`.consistency`); and the radio between the robots (delay, loss, send rates, switching,
stale messages), drawn up front per world and read by a pure step (:mod:`.links`). Imports
algebra, errors and checks; ``docs/networks.md`` states the convention and the sources.
"""

from .graph import Graph
from .consistency import check_relative_poses, consistent_poses, cycle_basis
from .links import Links, delivered_edges, inbox

__all__ = ["Graph", "Links", "check_relative_poses", "consistent_poses", "cycle_basis", "delivered_edges", "inbox"]

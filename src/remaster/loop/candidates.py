"""What the selection offers besides single blocks: the blocks a candidate brings with it (its
companions), the pairs offered together when neither passes alone, and the residual Gaussian
process's name among the effects.
"""

from __future__ import annotations

GP = "residual_gp"
# Blocks a candidate is offered with when the model lacks them: the link geometry is complete only
# with the marker offset, which holds the tool link's error that only moves the marker
# (`extensions.structural_redundancy`); offered alone, neither explains a rigid error of the tool.
COMPANIONS = {"link_geometry": ("marker_offset",)}
# Effects offered together when each was offered alone in a round and none passed: on an elastic arm
# the sag (compliance) and the link errors trade against each other, so that each alone leaves the
# other's share in the residual and cannot win, where both together can.
PAIRS = (("joint_compliance", "link_geometry"),)


def pair_name(pair) -> str:
    """A pair's name in the candidates and rounds: 'joint_compliance + link_geometry'."""
    return " + ".join(pair)


def with_companions(candidate: str, added, remaining) -> tuple[str, ...]:
    """The blocks a candidate brings into the model: itself and its companions not yet added (and
    still offered)."""
    return (candidate,) + tuple(c for c in COMPANIONS.get(candidate, ()) if c not in added and c in remaining)

"""The link-geometry block as a complete, minimal error model, checked against answers it did not
compute: the number of kinematic parameters position measurements can identify on an all-revolute
arm, 4R + 3 (Everett & Hollerbach; Zhuang, Roth & Hamano), counting the base's six and the marker's
three; completeness (dropping the absorbed parameters loses nothing the measurements can see) and
minimality (what is kept is independent) at configurations other than those the elimination used."""

import numpy as np
import pytest

from remaster.inference import blocks
from remaster.inference.extensions import structural_redundancy
from remaster.inference.readings import Readings

MARKER = np.array([-0.1, 0.0, 0.02])


def model_on(chain, q):
    zeros = np.zeros_like(q)
    data = Readings(np.arange(len(q)), q, np.zeros((len(q), 3)), zeros, zeros)
    return blocks.BlockModel(chain, data, MARKER, np.eye(4), ("marker_offset", "link_geometry"))


def rank(jacobian) -> int:
    unit = jacobian / np.linalg.norm(jacobian, axis=0)
    singular = np.linalg.svd(unit, compute_uv=False)
    return int(np.sum(singular > 1e-7 * singular[0]))


@pytest.mark.parametrize("robot, joints", [("iiwa", 7), ("ur5_dh", 6)])
def test_what_is_kept_is_complete_and_minimal(robot, joints, request, rng):
    chain = request.getfixturevalue(robot)
    q = rng.uniform(np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi), (150, joints))
    model = model_on(chain, q)
    absorbed = structural_redundancy(model)
    jacobian = model.jacobian(np.zeros(len(model.names)), 1e-6)
    kept = [i for i, n in enumerate(model.names) if n not in absorbed]
    base = [i for i, n in enumerate(model.names) if model.block_of[n] != "link_geometry"]
    links_kept = [i for i in kept if i not in base]
    # complete: every parameter the measurements see is still seen
    assert rank(jacobian[:, kept]) == rank(jacobian)
    # minimal: each kept link parameter adds a direction of its own
    assert rank(jacobian[:, kept]) == rank(jacobian[:, base]) + len(links_kept)
    # the published count of identifiable parameters for position measurements
    assert rank(jacobian) == 4 * joints + 3
    # and what absorbs the base link's and the tool's errors is named
    assert all(absorbed[f"link_geometry.F1.{p}"].startswith("absorbed at every configuration") for p in "x y z".split())
    assert all("marker_offset" in absorbed[f"link_geometry.tool.{p}"] for p in "x y z".split())

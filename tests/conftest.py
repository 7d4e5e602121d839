"""Shared fixtures: the bundled iiwa model and a DH robot (UR5 nominal table)."""

from pathlib import Path

import numpy as np
import pytest

from remaster.robot import kinematics

REPO = Path(__file__).resolve().parents[1]
IIWA_URDF = REPO / "data" / "robots" / "kuka_iiwa14.urdf"
UR5_URDF = Path(__file__).resolve().parent / "data" / "ur5_nominal.urdf"
# Universal Robots UR5 nominal standard DH table [a, alpha, d, theta offset]; ur5_nominal.urdf is the same chain.
UR5_DH = [
    [0.0, np.pi / 2, 0.089159, 0.0],
    [-0.425, 0.0, 0.0, 0.0],
    [-0.39225, 0.0, 0.0, 0.0],
    [0.0, np.pi / 2, 0.10915, 0.0],
    [0.0, -np.pi / 2, 0.09465, 0.0],
    [0.0, 0.0, 0.0823, 0.0],
]


@pytest.fixture(scope="session")
def iiwa():
    return kinematics.chain_from_urdf(IIWA_URDF.read_text(), "iiwa_link_0", "iiwa_link_ee", source=str(IIWA_URDF))


@pytest.fixture(scope="session")
def ur5_dh():
    return kinematics.chain_from_dh(UR5_DH, "standard", name="ur5")


@pytest.fixture
def rng():
    return np.random.default_rng(20181113)


def loop_report(parameters=(), effects=(), closure=None, source="loop_closure.json", **fields):
    """A loop closure's report (`remaster.loop.report.LoopReport`) with what the later stages read:
    the refit's parameter rows, the effects added, the closure test, and neutral values for the rest
    (1 kg tool plate, 0.5 deg marks' tolerance); `fields` overrides any top-level key."""
    from remaster.loop.report import LoopReport

    content = {"effects_added": list(effects), "refit": {"parameters": list(parameters)},
               "settings": {"payload_mass_kg": 1.0, "payload_com_m": [0.0, 0.0, 0.02],
                            "priors": {"std_display_units": {"held_zero_offset_deg": 0.5}}},
               "sigma_after_mm": 0.01, "prior_dominated": [], "identifiability": {"dropped": {}},
               "closure": dict(closure or {}), "residual_gp": None, "warnings": [], **fields}
    return LoopReport.of(content, source)

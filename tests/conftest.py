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

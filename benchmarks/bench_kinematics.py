"""Batched forward kinematics vs a Pinocchio loop, 173 configurations of the iiwa (the paper's set).

Run: python benchmarks/bench_kinematics.py   (numbers go into benchmarks/README.md by hand-run, never into a test)
"""

from __future__ import annotations

import timeit
from pathlib import Path

import numpy as np
import pinocchio as pin

from remaster.robot import kinematics

URDF = Path(__file__).resolve().parents[1] / "data" / "robots" / "kuka_iiwa14.urdf"
N_CONFIGURATIONS = 173
MARKER = np.array([0.1, 0.0, 0.02])


def best_of(function, repeat: int = 7) -> float:
    """Best time per call (s) over `repeat` rounds of auto-sized loops."""
    timer = timeit.Timer(function)
    loops, _ = timer.autorange()
    return min(timer.repeat(repeat=repeat, number=loops)) / loops


def main() -> None:
    chain = kinematics.chain_from_urdf(URDF.read_text(), "iiwa_link_0", "iiwa_link_ee")
    q = np.random.default_rng(0).uniform(chain.lower, chain.upper, (N_CONFIGURATIONS, chain.n_joints))
    offsets = np.zeros(chain.n_joints)
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    frame = model.getFrameId("iiwa_link_ee")

    def pinocchio_loop():
        out = np.empty((len(q), 3))
        for i, qi in enumerate(q + offsets):
            pin.framesForwardKinematics(model, data, qi)
            out[i] = data.oMf[frame].act(MARKER)
        return out

    fk = kinematics.ForwardKinematics(chain, q)
    walkers = np.zeros((64, chain.n_joints))
    assert np.allclose(pinocchio_loop(), fk.points(MARKER, offsets), atol=1e-9)
    t_pin = best_of(pinocchio_loop)
    t_batched = best_of(lambda: fk.points(MARKER, offsets))
    t_cold = best_of(lambda: kinematics.marker_positions(chain, q, MARKER, offsets))
    t_walkers = best_of(lambda: fk.points(MARKER, walkers))
    print(f"marker positions, {N_CONFIGURATIONS} configurations of the iiwa")
    print(f"  Pinocchio loop                  {t_pin * 1e6:9.1f} us")
    print(f"  batched (precomputed sin/cos)   {t_batched * 1e6:9.1f} us   {t_pin / t_batched:5.1f}x faster")
    print(f"  batched (from scratch)          {t_cold * 1e6:9.1f} us   {t_pin / t_cold:5.1f}x faster")
    print(
        f"  batched, 64 offset vectors      {t_walkers * 1e6:9.1f} us   "
        f"{64 * t_pin / t_walkers:5.1f}x faster than 64 Pinocchio loops"
    )


if __name__ == "__main__":
    main()

"""The kernel of the Gaussian-process family: a squared exponential on the circle of each joint,

    k(q, q') = s^2 exp(-sum_j (1 - cos(q_j - q'_j)) / l_j^2),

over joint readings q (N,) rad (1 - cos d = 2 sin^2(d / 2): periodic in 2 pi, so one turn apart is
the same angle; over a small range it is the plain squared exponential of length l_j). A joint the
data never turn (range below `STILL`) has no lengthscale (inf) and the kernel ignores it.

Two forms of one kernel: `kernel` between any two sets of readings (prediction, cross-covariances),
and `shape_from_distances` on the per-joint distances of one set precomputed once (`circle_distances`),
for the fits that evaluate the kernel many times at changing lengthscales.

SI inside (m, rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STILL = 1e-6  # rad: a joint whose range is below this is not turned by the data
LENGTH_BOUNDS = (0.02, 50.0)  # rad


@dataclass(frozen=True)
class Hyperparameters:
    """lengthscales (N,) rad, inf for a joint the data never turn; signal_std s and noise_std (m,
    per axis); at_bounds: the hyperparameters a fit left on a bound of its search ('signal_std at
    its lower bound', 'q3 lengthscale at its upper bound'): there the data did not determine them."""

    lengthscales: np.ndarray
    signal_std: float
    noise_std: float
    at_bounds: tuple[str, ...] = ()

    @property
    def turned(self) -> np.ndarray:
        return np.isfinite(self.lengthscales)

    def report(self) -> dict:
        return {
            "lengthscales_rad": [None if not np.isfinite(v) else float(v) for v in self.lengthscales],
            "signal_std_m": self.signal_std,
            "noise_std_m": self.noise_std,
            **({"at_bounds": list(self.at_bounds)} if self.at_bounds else {}),
        }

    @classmethod
    def from_report(cls, report: dict) -> Hyperparameters:
        return cls(
            np.array([np.inf if v is None else float(v) for v in report["lengthscales_rad"]]),
            float(report["signal_std_m"]),
            float(report["noise_std_m"]),
            tuple(report.get("at_bounds", ())),
        )


def at_bounds(x, bounds, names, tolerance: float = 1e-3) -> tuple[str, ...]:
    """Which of a search's parameters x (k,) (logs) end within `tolerance` of their bounds (k pairs),
    named '<name> at its lower bound' or '... upper bound'."""
    out = []
    for value, (low, high), name in zip(np.asarray(x, dtype=float), bounds, names):
        if value - low < tolerance:
            out.append(f"{name} at its lower bound")
        elif high - value < tolerance:
            out.append(f"{name} at its upper bound")
    return tuple(out)


def turned_joints(q) -> np.ndarray:
    """(N,) bool: the joints readings q (n, N) rad turn (range above `STILL`)."""
    return np.ptp(np.asarray(q, dtype=float), axis=0) > STILL


def kernel(qa, qb, hyper: Hyperparameters) -> np.ndarray:
    """k(qa_i, qb_k) (na, nb) m^2 for readings qa (na, N) and qb (nb, N) rad."""
    turned = hyper.turned
    a, b = np.asarray(qa, dtype=float)[:, turned], np.asarray(qb, dtype=float)[:, turned]
    weight = 1.0 / hyper.lengthscales[turned] ** 2
    # sum_j w_j (1 - cos(a_j - b_j)) = sum w - (cos a w) . cos b - (sin a w) . sin b: two products
    exponent = weight.sum() - (np.cos(a) * weight) @ np.cos(b).T - (np.sin(a) * weight) @ np.sin(b).T
    return hyper.signal_std**2 * np.exp(-np.maximum(exponent, 0.0))


def covariance_with_noise(q, hyper: Hyperparameters) -> np.ndarray:
    """(n, n) m^2: K + noise^2 I, the covariance of each output of residuals at readings q (n, N) rad."""
    q = np.asarray(q, dtype=float)
    out = kernel(q, q, hyper)
    out[np.diag_indices_from(out)] += hyper.noise_std**2
    return out


def circle_distances(q) -> np.ndarray:
    """(J, n, n): 1 - cos(q_ij - q_kj) of each joint j of readings q (n, J) rad (pass the turned
    joints only), contiguous per joint."""
    q = np.asarray(q, dtype=float)
    return np.ascontiguousarray(np.moveaxis(1.0 - np.cos(q[:, None, :] - q[None, :, :]), -1, 0))


def shape_from_distances(distances, weights) -> np.ndarray:
    """(n, n): k / s^2 = exp(-sum_j w_j D_j) from distances (J, n, n) (`circle_distances`) and
    weights (J,) rad^-2, w_j = 1 / l_j^2."""
    return np.exp(-np.tensordot(weights, distances, axes=1))

"""The uncertainty budget: GUM's quadrature with known answers."""

import numpy as np

from remaster.analysis import budget
from remaster.inference.fit import LaplaceReport


def _laplace(jacobian, sigma):
    names = tuple(f"registration.{k}" for k in "xyz") + ("zero_offsets.q2", "zero_offsets.q3")
    covariance = sigma**2 * np.linalg.inv(jacobian.T @ jacobian)
    return LaplaceReport(
        names,
        np.zeros(5),
        np.sqrt(np.diag(covariance)),
        covariance,
        sigma,
        sigma,
        sigma / 50,
        names,
        {},
        (),
        (),
        (),
        40,
    )


def test_the_parameters_together_give_sigma_sqrt_p_over_3n_and_the_parts_add_up():
    """With the least-squares covariance sigma^2 (J^T J)^-1 the mean prediction variance over the
    3n residuals is sigma^2 P / 3n (the trace of the hat matrix is P); the shares of u_c^2 add to
    100 % and u_c is their root sum of squares."""
    rng = np.random.default_rng(2)
    jacobian = rng.normal(size=(120, 5))
    sigma, noise = 0.5e-3, 0.1e-3
    laplace = _laplace(jacobian, sigma)
    assert np.isclose(budget.propagated(jacobian, laplace.covariance, range(5)), sigma * np.sqrt(5 / 120))
    rows = {r["Component"]: r for r in budget.budget_rows(jacobian, laplace, noise, loop_sigma=0.12e-3)}
    parts = [
        "sensor noise",
        "registration",
        "zero-offsets",
        "registration x zero-offsets correlation",
        "what the model lacks",
    ]
    assert np.isclose(sum(rows[p]["share of u_c^2 (%)"] for p in parts), 100.0)
    lacks = np.sqrt(sigma**2 - noise**2)
    combined = np.sqrt(noise**2 + lacks**2 + 5 / 120 * sigma**2)
    assert np.isclose(rows["combined u_c"]["u per axis (mm)"], combined * 1e3)
    assert np.isclose(rows["expanded U (k = 2)"]["u per axis (mm)"], 2 * combined * 1e3)
    assert np.isclose(rows["what the model lacks"]["u per axis (mm)"], lacks * 1e3)
    assert np.isclose(rows["what the model lacks after the loop closure"]["u per axis (mm)"], np.sqrt(0.12**2 - 0.1**2))


def test_without_a_stated_noise_sigma_is_noise_and_what_the_model_lacks_together():
    jacobian = np.random.default_rng(3).normal(size=(60, 5))
    rows = {r["Component"]: r for r in budget.budget_rows(jacobian, _laplace(jacobian, 1e-3), None)}
    assert "what the model lacks" not in rows and rows["sensor noise"]["source"].startswith("not stated")
    assert np.isclose(rows["sensor noise"]["u per axis (mm)"], 1.0)

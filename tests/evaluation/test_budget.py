"""The uncertainty budget: GUM's quadrature, degrees of freedom and systematic term with known answers."""

import numpy as np
from scipy import stats

from remaster.evaluation import budget
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


def test_a_toy_budget_by_hand():
    """With the least-squares covariance sigma^2 (J^T J)^-1 the mean prediction variance over the
    3n residuals is sigma^2 P / 3n (the trace of the hat matrix is P): one fitted-parameter row.
    u_c is the root sum of squares of the noise, the MPE / sqrt(3) and that row; its dof by
    Welch-Satterthwaite (only the fitted row is finite: 3n - P - 1), U = t_0.975(nu) u_c; the model
    discrepancy is systematic: not in u_c, its 95 % bound added to U."""
    rng = np.random.default_rng(2)
    jacobian = rng.normal(size=(120, 5))
    sigma, noise, mpe = 0.5e-3, 0.1e-3, 0.3e-3
    residuals = rng.normal(0, sigma, (40, 3))
    laplace = _laplace(jacobian, sigma)
    assert np.isclose(budget.propagated(jacobian, laplace.covariance, range(5)), sigma * np.sqrt(5 / 120))
    rows = budget.budget_rows(jacobian, laplace, noise, residuals, loop_sigma=0.12e-3, mpe=mpe)
    by = {r["Component"]: r for r in rows}
    fitted = sigma * np.sqrt(5 / 120)
    assert np.isclose(by["fitted parameters (registration and zero-offsets)"]["u per axis (mm)"], fitted * 1e3)
    assert not any(r["Component"] in ("registration", "zero-offsets") for r in rows)  # no split equal by construction
    assert by["measurement noise"]["Type"] == "B" and by["measurement noise"]["dof"] == np.inf
    instrument = by["instrument MPE"]
    assert instrument["Distribution"] == "rectangular" and np.isclose(instrument["u per axis (mm)"], 0.3 / np.sqrt(3))
    combined = np.sqrt(noise**2 + mpe**2 / 3 + fitted**2)
    nu = combined**4 / (fitted**4 / (120 - 5 - 1))
    assert np.isclose(by["combined u_c"]["u per axis (mm)"], combined * 1e3) and np.isclose(
        by["combined u_c"]["dof"], nu
    )
    shares = [
        by[c]["share of u_c^2 (%)"]
        for c in ("measurement noise", "instrument MPE", "fitted parameters (registration and zero-offsets)")
    ]
    assert np.isclose(sum(shares), 100.0)
    k = stats.t.ppf(0.975, nu)
    expanded = next(r for r in rows if r["Component"].startswith("expanded U"))
    assert np.isclose(expanded["u per axis (mm)"], k * combined * 1e3) and f"{k:.2f}" in expanded["Component"]
    discrepancy = by["model discrepancy"]
    assert discrepancy["Type"] == "systematic" and np.isnan(discrepancy["share of u_c^2 (%)"])
    assert np.isclose(discrepancy["u per axis (mm)"], np.sqrt(sigma**2 - noise**2) * 1e3)
    bound = np.quantile(np.abs(residuals), 0.95)
    assert np.isclose(by["model discrepancy, 95 % bound"]["u per axis (mm)"], bound * 1e3)
    assert np.isclose(by["U + model discrepancy bound"]["u per axis (mm)"], (k * combined + bound) * 1e3)
    after = by["model discrepancy after the loop closure"]
    assert np.isclose(after["u per axis (mm)"], np.sqrt(0.12**2 - 0.1**2))


def test_without_a_stated_noise_or_mpe_the_rows_say_what_they_hold():
    """No noise stated: no row is called sensor noise; the fit's sigma is the residual scatter (Type
    A, 3n - P - 1 dof) holding the noise and the model discrepancy together, and no systematic row
    can be split off; no MPE stated: its row says so and adds nothing."""
    jacobian = np.random.default_rng(3).normal(size=(60, 5))
    rows = budget.budget_rows(jacobian, _laplace(jacobian, 1e-3), None)
    by = {r["Component"]: r for r in rows}
    assert not any("sensor noise" in r["Component"] for r in rows)
    scatter = by["residual scatter: noise and model discrepancy together"]
    assert scatter["Type"] == "A" and scatter["dof"] == 60 - 5 - 1 and np.isclose(scatter["u per axis (mm)"], 1.0)
    assert "model discrepancy" not in by and "not stated" in by["instrument MPE"]["source"]
    assert np.isnan(by["instrument MPE"]["u per axis (mm)"])
    assert np.isclose(by["combined u_c"]["u per axis (mm)"], np.sqrt(1.0 + 5 / 60))
    a, b = 1.0, 5 / 60  # the two variances (mm^2), both of 54 dof
    assert np.isclose(by["combined u_c"]["dof"], 54 * (a + b) ** 2 / (a**2 + b**2))

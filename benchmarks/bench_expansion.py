"""The paper's sum of squares over the rows against its expansion in the zero-offsets, side by side.

Every sampler of the paper's model (the paper's chain, the default sampler, emcee) evaluates
sum_i |m_i - T p_i(theta)|^2 hundreds of thousands of times. Summed over the rows
(`_kernels.registered_sum_squares`) an evaluation grows with them; from the expansion
(`_kernels.expansion_sums` once, then `_kernels.expanded_sum_squares`) it costs the same at any
number of rows. Per size (simulated iiwa, random configurations, a 10 um laser tracker, the
registration and zero-offsets known): the time of one evaluation each way (median of repeated
calls, the two alternated in one process), the expansion's one-time cost, and the largest
difference between the two near the truth (within 1e-4 of it), in units of 2 sigma^2 (a difference
of 1 there moves a log-posterior by 1), and far from it (0.01 rad, where the energies are large),
relative.

Writes benchmarks/results/expansion.json and .md and the table into benchmarks/README.md between
its bench_expansion markers. From the repository root:
    .venv/bin/python benchmarks/bench_expansion.py [rows ...]   (default 1000 10000 100000 1000000)
"""

from __future__ import annotations

import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import publish  # noqa: E402
from remaster import _kernels, spatial  # noqa: E402
from remaster.inference.blocks import paper_model  # noqa: E402
from remaster.robot import kinematics  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
IIWA_URDF = REPO / "data" / "robots" / "kuka_iiwa14.urdf"
NOISE = 1e-5  # m per axis


def campaign(rows: int, rng: np.random.Generator):
    """The paper's model on a simulated campaign of `rows` readings, and its true parameters."""
    chain = kinematics.chain_from_urdf(IIWA_URDF.read_text(), "iiwa_link_0", "iiwa_link_ee", source=str(IIWA_URDF))
    q = rng.uniform(np.maximum(chain.lower, -2.5), np.minimum(chain.upper, 2.5), (rows, chain.n_joints))
    offsets = rng.normal(0.0, np.radians(0.3), chain.n_joints)
    marker = np.array([0.1, 0.0, 0.02])
    t_nr = spatial.homogeneous(spatial.euler_zyx_to_matrix(2.0, 0.1, -0.2), [1.5, -0.3, 0.8])
    points = kinematics.marker_positions(chain, q + offsets, marker)
    measured = spatial.transform_points(t_nr, points) + rng.normal(0.0, NOISE, points.shape)
    model = paper_model(chain, q, measured, marker, t_nr, fixed={"zero_offsets.q1": offsets[0]})
    return model, np.concatenate([np.zeros(6), offsets[1:]])


def _seconds(call, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return float(np.median(times))


def measure(rows: int, rng: np.random.Generator) -> dict:
    model, truth = campaign(rows, rng)
    started = time.perf_counter()
    expansion = model._expansion()
    built = time.perf_counter() - started
    thetas = np.vstack([truth + rng.normal(0, scale, (4, len(truth))) for scale in (1e-6, 1e-4, 1e-2)])
    every = np.ascontiguousarray(model.full(thetas))
    kernel = (model._kernel.rotations, model._kernel.shifts, model._start, model._cos_q, model._sin_q)

    def summed(stack=every):
        return _kernels.registered_sum_squares(*kernel, stack, model.t_nr, model._measured_t)

    def expanded(stack=every):
        return _kernels.expanded_sum_squares(expansion, stack, model.t_nr)

    exact, fast = summed(), expanded()
    near = slice(0, 8)  # within 1e-4 of the truth: where the chain spends its time
    difference = float(np.max(np.abs(exact[near] - fast[near])) / (2 * NOISE**2))
    relative = float(np.max(np.abs(exact[8:] - fast[8:]) / exact[8:]))
    one = every[:1]
    repeats = max(5, min(2000, int(2e7 / rows)))
    per_summed, per_expanded = [], []
    for _ in range(3):  # alternated, so that the machine's load falls on both
        per_summed.append(_seconds(lambda: summed(one), repeats))
        per_expanded.append(_seconds(lambda: expanded(one), repeats))
    return {
        "rows": rows,
        "summed_us": 1e6 * float(np.median(per_summed)),
        "expanded_us": 1e6 * float(np.median(per_expanded)),
        "expansion_s": built,
        "max_difference_over_2sigma2": difference,
        "max_relative_difference_far": relative,
    }


def markdown(record: dict) -> str:
    lines = [
        f"Measured {record['date']} by `bench_expansion.py` (iiwa, 7 joints: 2187 terms; a 10 um tracker):",
        "",
        "| rows | one evaluation summed over the rows | from the expansion | ratio | the expansion, once | "
        "largest difference near the truth / 2 sigma^2 | largest relative difference far from it (0.01 rad) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in record["runs"]:
        lines.append(
            f"| {r['rows']:,} | {r['summed_us']:,.0f} µs | {r['expanded_us']:.0f} µs | "
            f"{r['summed_us'] / r['expanded_us']:,.1f} | {r['expansion_s']:.2f} s | "
            f"{r['max_difference_over_2sigma2']:.1e} | {r['max_relative_difference_far']:.1e} |"
        )
    return "\n".join(lines)


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [1000, 10_000, 100_000, 1_000_000]
    rng = np.random.default_rng(2026)
    runs = [measure(rows, rng) for rows in sizes]
    record = {"date": date.today().isoformat(), "runs": runs}
    publish(REPO / "benchmarks" / "results", "expansion", record, markdown(record), REPO / "benchmarks" / "README.md")


if __name__ == "__main__":
    main()

"""Two calibrations compared by what they predict: drift between consecutive campaigns of one robot
and the agreement of one campaign's sensors, as the change of predicted marker position
(`remaster.calibration.prediction` makes the predictions). The drift is compared where both
campaigns measured: at configurations inside both campaigns' measured domains (`robot.nearness`),
drawn near each campaign's data and kept where they are near the other's, since elsewhere two
calibrations differ by what their priors say, not by what the robot did; a pair whose domains do
not meet is not compared (`status` says so). Nearness takes each joint on the circle (a campaign
that read q1 one turn from the other's measured the same configurations) but, per model, the
joints the model corrects in proportion to the reading (a joint scale): there a turn is not
measured. Where both campaigns reached enough of those configurations with the same readings
(every joint's reading as it is, not on the circle), only those are compared; where they share them
only a turn apart, the change is shown (`turn_apart`) and not flagged: the robot at q and at
q + 2 pi is one only if all it does is periodic in the turn, which neither campaign's data can
tell. The agreement of one campaign's sensors is compared inside both sensors' domains too.

Two calibrations A and B are compared at one fixed set of configurations q (n, N) by
d(q) = |p_B(q) - p_A(q)|, both at their posterior means: `mean_mm`, `p95_mm` over q, in the robot
frame. What is tested is the change left after the rigid motion that best carries p_B onto p_A
(Kabsch over the q): `aligned_mean_mm`, the mean of |T p_B(q) - p_A(q)|. Each campaign's robot frame is
fixed by its own registration, so a rigid motion of every prediction is what re-registering the
sensor absorbs, not the robot's drift: a zero-offset one campaign could not see (a joint held at its
mark) moves a marker on one tool orientation rigidly, and the paper's accuracy is post-registration
for the same reason. Its null distribution (no change, only posterior uncertainty) comes from draw
pairs k = 1..K: the deviations e_k(q) = [p_B(draw_B,k)(q) - p_B(mean_B)(q)] - [p_A(draw_A,k)(q) -
p_A(mean_A)(q)], each left after the rigid motion that best carries p_A(mean_A) + e_k onto
p_A(mean_A), whose mean over q is the statistic under no change. `null_p95_of_aligned_mean_mm` is its
95th percentile over the K pairs and the pair is `flagged` when the observed aligned mean exceeds it
(a one-sided test at 5 %: the change of prediction is larger than the two posteriors' own spread
explains). Between two campaigns, a change beyond the null (`beyond_null`) is flagged only where both
loops closed (`loops_closed`), as a parameter's drift is (`remaster.comparing.comparison`): a loop
that did not close leaves in its residual what its model lacks, and its predictions carry that in its
own design's proportions. Without posterior samples on one side (MCMC off) there is no null: NaN and
not flagged.

SI inside (m, rad); the tables are in mm.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

from .. import identity, seeding
from ..calibration.prediction import MODELS, Calibrated, Calibration
from ..errors import InputError
from ..inference import metrics
from ..inference.parameter_blocks import block_parameters
from ..robot import registration
from ..robot.kinematics import KinematicChain
from ..robot.nearness import Nearness
from ..spatial import transform_points
from ..units import MM
from . import comparison

NULL_QUANTILE = 0.95
# configurations inside both campaigns' domains below which a drift is not compared: too few to
# tell a change of prediction from the posteriors' spread
MIN_SHARED_CONFIGURATIONS = 20
TURN_APART = (
    "compared a turn apart: both campaigns measured these configurations, but with a joint read a turn from "
    "the other's (or the other way round across +-180 deg); a change here is the robot's drift or an effect "
    "not periodic in the turn (a cable's wind-up, a transmission error of another period), which no data of "
    "either campaign can tell apart: shown, not flagged"
)


PREDICTION_COLUMNS = [
    "count",
    "mean_mm",
    "p95_mm",
    "aligned_mean_mm",
    "draw_pairs",
    "null_p95_of_aligned_mean_mm",
    "beyond_null",
    "loops_closed",
    "turn_apart",
    "flagged",
    "status",
]


DRIFT_COLUMNS = [
    "robot",
    "kind",
    "model",
    "campaign_a",
    "date_a",
    "sensor_a",
    "campaign_b",
    "date_b",
    "sensor_b",
    "effects_a",
    "effects_b",
] + PREDICTION_COLUMNS


AGREEMENT_COLUMNS = [
    "campaign",
    "date",
    "robot",
    "model",
    "sensor_a",
    "sensor_b",
    "effects_a",
    "effects_b",
] + PREDICTION_COLUMNS


def compare_predictions(
    chain: KinematicChain, q, marker, a: Calibration, b: Calibration, draw_pairs: int, rng: np.random.Generator
) -> dict:
    """What B predicts against what A predicts at configurations q (n, N) rad, marker (3,) m
    (flange frame, each model's marker offset added): count (the configurations), mean_mm and p95_mm of
    |p_B - p_A| at the posterior means, aligned_mean_mm after the rigid motion that best carries p_B
    onto p_A, draw_pairs and null_p95_of_aligned_mean_mm from `draw_pairs`
    posterior draw pairs (rng chooses the draws), flagged (see the module docstring). A joint one
    calibration did not see (`Calibration.unseen_std`) is drawn at the marks' tolerance in its
    draws; one neither saw, held at the same value, is not drawn."""
    # a joint neither campaign saw is held at the same mark in both: its unknown turn is the same
    # robot's in both predictions and cancels in their difference, so neither draws it
    both = {n for n in a.drawn_unseen.keys() & b.drawn_unseen.keys() if a.values[n] == b.values[n]}
    a, b = (replace(c, unseen_std={n: s for n, s in c.unseen_std.items() if n not in both}) for c in (a, b))
    pa, pb = a.predictor(chain, q, marker), b.predictor(chain, q, marker)
    mean_a, mean_b = pa.points(a.values), pb.points(b.values)
    distance = np.linalg.norm(mean_b - mean_a, axis=1)
    aligned = float(np.mean(_aligned(mean_a, (mean_b - mean_a)[None])))
    row = {
        **metrics.in_mm(metrics.error_summary(distance, ("mean", "p95"))),
        "aligned_mean_mm": aligned / MM,
        "draw_pairs": 0,
        "null_p95_of_aligned_mean_mm": np.nan,
        "flagged": False,
    }
    draws_a, draws_b = a.draw_values(draw_pairs, rng), b.draw_values(draw_pairs, rng)
    if draws_a is None or draws_b is None:
        missing = " and ".join(s for s, d in (("A", draws_a), ("B", draws_b)) if d is None)
        return {**row, "status": f"no null: no posterior samples of {missing}"}
    deviations = np.array([(pb.points(db) - mean_b) - (pa.points(da) - mean_a) for da, db in zip(draws_a, draws_b)])
    null = _aligned(mean_a, deviations).mean(axis=1)
    threshold = float(np.quantile(null, NULL_QUANTILE))
    flagged = bool(aligned > threshold)
    return {
        **row,
        "draw_pairs": int(len(null)),
        "null_p95_of_aligned_mean_mm": threshold / MM,
        "flagged": flagged,
        "status": "compared",
    }


def _aligned(points, changes) -> np.ndarray:
    """(K, n) what is left of K sets of changes c_k (K, n, 3) m of points p (n, 3) m after the rigid
    motion T_k that best carries p onto p + c_k (what a re-registration absorbs): |p + c_k - T_k p|."""
    moved = points[None] + changes
    transforms = registration.rigid_transforms(points, moved)
    return np.linalg.norm(moved - transform_points(transforms[:, None], points[None]), axis=2)


def _entries_frame(entries: Sequence[Calibrated]) -> pd.DataFrame:
    """The entries as over-time rows (campaign, date, robot, sensor, kind, entry index), so that
    `comparison`'s pairing of consecutive campaigns and of a campaign's sensors applies."""
    seen = set()
    for e in entries:
        if (e.campaign, e.sensor.name) in seen:
            raise InputError("given twice", file=f"{e.campaign}/{e.sensor.name}")
        seen.add((e.campaign, e.sensor.name))
    return pd.DataFrame(
        {
            "campaign": [e.campaign for e in entries],
            "date": [e.date for e in entries],
            "robot": [e.robot for e in entries],
            "sensor": [e.sensor.name for e in entries],
            "kind": [e.kind for e in entries],
            "entry": np.arange(len(entries)),
        }
    )


def _compared_models(a: Calibrated, b: Calibrated) -> list[str]:
    """The models both entries have, the nominal one left out, in `MODELS`' order."""
    return [m for m in MODELS if m in a.models and m in b.models and m != "nominal"]


def _pair_rows(
    a: Calibrated,
    b: Calibrated,
    q,
    marker,
    sizes: tuple[int, int],
    labels: dict,
    models=None,
    turn_apart: bool = False,
) -> list[dict]:
    """One row per model both entries have (of `models` when given): labels, effects and
    `compare_predictions` (sizes: draw_pairs, seed); the draws of each pair and model come from
    their own generator, so a row does not depend on the others. turn_apart: q are configurations
    near both entries' data only on the circle (`_shared`): a change there is shown, not
    flagged."""
    draw_pairs, seed = sizes
    rows = []
    for model in [m for m in _compared_models(a, b) if models is None or m in models]:
        ca, cb = a.models[model], b.models[model]
        rng = seeding.generator(
            seed,
            "comparison",
            identity.robot_slug(a.robot),
            a.campaign,
            a.sensor.name,
            b.campaign,
            b.sensor.name,
            model,
        )
        compared = compare_predictions(a.chain, q, marker, ca, cb, draw_pairs, rng)
        closed = comparison.both_closed(a.loop_closed, b.loop_closed)
        # beyond the null, but a loop not closed carries what its model lacks: not the robot's drift
        flagged = compared["flagged"] and closed is not False and not turn_apart
        if turn_apart and compared["status"] == "compared":
            compared["status"] = TURN_APART
        rows.append(
            {
                **labels,
                "model": model,
                "effects_a": ca.effects,
                "effects_b": cb.effects,
                **compared,
                "beyond_null": compared["flagged"],
                "loops_closed": closed,
                "turn_apart": turn_apart,
                "flagged": flagged,
            }
        )
    return rows


def _table(rows: list[dict], columns: list[str]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=columns) if rows else pd.DataFrame(columns=columns)


def shared_configurations(a: Calibrated, b: Calibrated, n: int, seed: int, model: str | None = None) -> np.ndarray:
    """Configurations (k, N) rad, k <= 2n, inside both entries' measured domains (`Nearness` of the
    readings each fit used, on the circle of each joint but those the entry's `model`, when given,
    corrects in proportion to the reading: `Calibration.linear_joints`): n drawn near each entry's
    data (the generator of (seed, 'shared domain', robot slug, both campaigns and sensors), the same
    draws for every model), kept where the other's data are near too."""
    return _shared(a, b, n, seed, model)[0]


def _shared(a: Calibrated, b: Calibrated, n: int, seed: int, model: str | None) -> tuple[np.ndarray, np.ndarray]:
    """`shared_configurations` q (k, N) and, (k,) bool, whether each is near both entries' data with
    every joint's reading taken as it is, on the line (the same spacing): where it is not, one
    campaign reached it only with a joint a turn from its reading (or the other way round across
    +-pi), and a model periodic in that joint sees one configuration, but the robot there is one
    only if everything it does is periodic in the joint."""
    rng = seeding.generator(
        seed, "shared domain", identity.robot_slug(a.robot), a.campaign, a.sensor.name, b.campaign, b.sensor.name
    )
    near = [
        Nearness.of(
            e.chain,
            e.sensor.fit_readings(e.excluded),
            e.sensor.marker,
            e.models[model].linear_joints if model in e.models else (),
        )
        for e in (a, b)
    ]
    q = np.vstack([domain.draw(n, rng, a.chain.lower, a.chain.upper) for domain in near])
    q = q[near[0].inside(q) & near[1].inside(q)]
    every_joint = tuple(range(a.chain.n_joints))
    as_read = [replace(domain, linear=every_joint).inside(q) if len(q) else np.zeros(0, bool) for domain in near]
    return q, as_read[0] & as_read[1]


def prediction_drift(
    entries: Iterable[Calibrated], n_configurations: int = 1000, seed: int = 0, draw_pairs: int = 200
) -> pd.DataFrame:
    """Drift between consecutive campaigns of one robot and sensor kind (pairs as
    `comparison.drift_between` makes them) as the change of predicted marker position, robot
    frame, at configurations inside both campaigns' measured domains (`shared_configurations`, up
    to 2 n_configurations), per model (paper, loop); fewer than `MIN_SHARED_CONFIGURATIONS` there:
    not compared, not flagged. The marker is campaign A's sensor's nominal one, the models' marker
    offsets left out: a marker is part of a campaign's set-up (remounted between campaigns, refitted
    in a transfer), not of the robot, and a last joint's held zero-offset that an offset carried is
    drawn instead; where either sensor measured one marker's position, the point compared is the
    marker's foot on the last joint's axis, which that turn does not move. Columns DRIFT_COLUMNS (mm)."""
    entries = list(entries)
    frame = _entries_frame(entries)
    rows = []
    for robot, kind, a_rows, b_rows in comparison.consecutive_pairs(frame):
        a, b = entries[int(a_rows["entry"].iloc[0])], entries[int(b_rows["entry"].iloc[0])]
        labels = {
            "robot": robot,
            "kind": kind,
            "campaign_a": a.campaign,
            "date_a": a.date,
            "sensor_a": a.sensor.name,
            "campaign_b": b.campaign,
            "date_b": b.date,
            "sensor_b": b.sensor.name,
        }
        rows += _rows_in_both_domains(a, b, a.sensor.marker, (n_configurations, seed, draw_pairs), labels)
    return _table(rows, DRIFT_COLUMNS)


def prediction_agreement(
    entries: Iterable[Calibrated], n_configurations: int = 1000, seed: int = 0, draw_pairs: int = 200
) -> pd.DataFrame:
    """The sensors' agreement within each campaign (pairs as `comparison.sensor_agreement` makes
    them) as the difference of predicted positions, robot frame, at configurations inside both
    sensors' measured domains (as `prediction_drift`: elsewhere two calibrations differ by what
    their priors say), per model. The point is the midpoint of the two sensors' nominal markers,
    and each sensor's set-up is left out (`_without_set_up`): each sensor has its own marker, and
    the comparison is of the robot. Columns AGREEMENT_COLUMNS (mm)."""
    entries = list(entries)
    frame = _entries_frame(entries)
    rows = []
    for a_rows, b_rows in comparison.sensor_pairs(frame):
        a, b = entries[int(a_rows["entry"].iloc[0])], entries[int(b_rows["entry"].iloc[0])]
        labels = {
            "campaign": a.campaign,
            "date": a.date,
            "robot": a.robot,
            "sensor_a": a.sensor.name,
            "sensor_b": b.sensor.name,
        }
        marker = (np.asarray(a.sensor.marker) + np.asarray(b.sensor.marker)) / 2.0
        rows += _rows_in_both_domains(a, b, marker, (n_configurations, seed, draw_pairs), labels)
    return _table(rows, AGREEMENT_COLUMNS)


def _rows_in_both_domains(
    a: Calibrated, b: Calibrated, marker, sizes: tuple[int, int, int], labels: dict
) -> list[dict]:
    """One row per model both entries have, compared at configurations inside both entries' measured
    domains (`shared_configurations`; sizes: n_configurations, seed, draw_pairs), each entry's
    set-up left out (`_without_set_up`): at those both reached with the same readings
    (`_shared`) when there are MIN_SHARED_CONFIGURATIONS of them, else at every one, a turn
    apart (`turn_apart`: shown, not flagged); fewer than MIN_SHARED_CONFIGURATIONS: not compared."""
    n_configurations, seed, draw_pairs = sizes
    rows, robot_a, robot_b = [], _without_set_up(a), _without_set_up(b)
    if not (a.sensor.has_orientation and b.sensor.has_orientation):
        # one marker's position cannot tell the last joint's turn from the marker's mount: compared
        # where that turn moves nothing, the marker's foot on the last joint's axis
        marker = on_last_axis(a.chain, marker)
    shared: dict[tuple, tuple[np.ndarray, bool]] = {}  # by the models' linear joints: most models share them
    for model in _compared_models(a, b):
        key = (a.models[model].linear_joints, b.models[model].linear_joints)
        if key not in shared:
            q, as_read = _shared(a, b, n_configurations, seed, model)
            same = q[as_read]
            shared[key] = (same, False) if len(same) >= MIN_SHARED_CONFIGURATIONS else (q, True)
        q, turn_apart = shared[key]
        if len(q) >= MIN_SHARED_CONFIGURATIONS:
            rows += _pair_rows(robot_a, robot_b, q, marker, (draw_pairs, seed), labels, (model,), turn_apart)
            continue
        status = (
            f"not compared: {len(q)} configurations inside both measured domains (fewer than "
            f"{MIN_SHARED_CONFIGURATIONS}): where one did not measure, its calibration is its priors'"
        )
        rows.append(
            {
                **labels,
                "model": model,
                "effects_a": a.models[model].effects,
                "effects_b": b.models[model].effects,
                "count": len(q),
                "mean_mm": np.nan,
                "p95_mm": np.nan,
                "draw_pairs": 0,
                "aligned_mean_mm": np.nan,
                "null_p95_of_aligned_mean_mm": np.nan,
                "beyond_null": False,
                "loops_closed": comparison.both_closed(a.loop_closed, b.loop_closed),
                "turn_apart": False,
                "flagged": False,
                "status": status,
            }
        )
    return rows


def _without_set_up(entry: Calibrated) -> Calibrated:
    """The entry as a robot, its campaign's set-up left out: its models' marker offsets (values,
    blocks and draws) and, where the sensor measured one marker's position only, what its last
    joint's zero-offset owes to the marker's mount. At the marker a turn of the last joint moves the
    marker as its place on the flange does, so one marker cannot tell them apart: a model without
    a marker offset carries the marker's mount error in that turn (a remounted marker reads as a
    turned joint), one with a marker offset held the turn (the offset carried it). Its draws take
    the turn about its value at the mount's uncertainty (`_turn_of_mount`), in every model of such a
    sensor; a full-pose probe's orientations tell the turn from the mount, and there it is drawn
    only where the data did not see it."""
    names = set(block_parameters("marker_offset", entry.chain).names)
    last = f"zero_offsets.q{entry.chain.n_joints}"
    mount = None if entry.sensor.has_orientation else _turn_of_mount(entry)

    def strip(c: Calibration) -> Calibration:
        turned = mount is not None and last in c.values and c.draws is not None and not c.draws.empty
        if "marker_offset" not in c.blocks and not turned:
            return c
        draws = None if c.draws is None else c.draws.drop(columns=[n for n in names if n in c.draws.columns])
        unseen = dict(c.unseen_std)
        if turned:
            unseen[last] = max(unseen.get(last, 0.0), mount)
        return replace(
            c,
            values={k: v for k, v in c.values.items() if k not in names},
            blocks=tuple(b for b in c.blocks if b != "marker_offset"),
            draws=draws,
            unseen_std=unseen,
            carried=frozenset(),  # no marker offset carries the last joint's turn any more: drawn
        )

    return entry._replace(models={m: strip(c) for m, c in entry.models.items()})


def on_last_axis(chain: KinematicChain, point) -> np.ndarray:
    """(3,) m the point of the last joint's axis nearest `point` (3,) m, both in the flange frame."""
    tool = np.asarray(chain.tool_transform, dtype=float)
    in_joint = tool[:3, :3] @ np.asarray(point, dtype=float) + tool[:3, 3]  # the last joint's frame
    axis = np.asarray(chain.joint_axes[-1], dtype=float)
    foot = (in_joint @ axis) * axis
    return tool[:3, :3].T @ (foot - tool[:3, 3])


def _turn_of_mount(entry: Calibrated) -> float:
    """The std (rad) of the last joint's turn that the marker's mount (its prior std per axis,
    `Calibrated.marker_std`) leaves open: the mount over the nominal marker's distance from the last
    joint's axis, at most pi (a marker on the axis: any turn)."""
    marker = np.asarray(entry.sensor.marker, dtype=float)
    radius = float(np.linalg.norm(marker - on_last_axis(entry.chain, marker)))
    return float(min(entry.marker_std / radius, np.pi)) if radius > 0 else float(np.pi)


PREDICTION_TABLES = {"prediction_drift": prediction_drift, "prediction_agreement": prediction_agreement}


CAPTIONS = {  # the tables' and figures' captions, beside `tables.CAPTIONS`
    "transfer": "Transfer between campaigns of one robot: each campaign's calibration (nominal, paper, loop) on "
    "each campaign's validation set of the same sensor, registration and marker refitted on that campaign's "
    "optimization set with the calibration's kinematics frozen (registration, sensor scale, marker and drift "
    "not transferred); the diagonal is the campaign's own validation of its kinematics.",
    "transfer_nominal": "Transfer heat-map, nominal kinematics: validation RMSE (mm), calibrated on (rows) against "
    "evaluated on (columns)",
    "transfer_paper": "Transfer heat-map, the paper's model: validation RMSE (mm), calibrated on (rows) against "
    "evaluated on (columns)",
    "transfer_loop": "Transfer heat-map, the loop closure's model: validation RMSE (mm), calibrated on (rows) "
    "against evaluated on (columns)",
    "prediction_drift": "Drift between consecutive campaigns of one robot and sensor kind as the change of "
    "predicted marker position (robot frame, mm) at configurations inside both campaigns' measured domains "
    "(count); flagged where the mean change left after the best rigid motion (what a re-registration absorbs) "
    "exceeds the 95th percentile of its posterior null and both loops closed; where the campaigns reached "
    "these configurations only with a joint a turn apart (turn_apart), shown and not flagged; not compared "
    "where the domains do not meet.",
    "prediction_agreement": "Agreement of the sensors of each campaign as the difference of predicted positions "
    "(robot frame, mm) at configurations inside both sensors' measured domains; flagged as for the drift.",
}

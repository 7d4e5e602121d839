"""The loop closure's long tables and back: the candidates' signatures of every round, and the
residuals before and after (signatures.parquet and residuals.parquet of `loop_closure.LoopClosure.write`).
Lengths in m.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .scoring import Signature


def signatures_frame(signatures: dict[int, dict[str, Signature]]) -> pd.DataFrame:
    """Long table of every round's candidate signatures: round, candidate, point, axis, residual_m, effect_m."""
    frames = []
    for round_number, candidates in signatures.items():
        for name, signature in candidates.items():
            n = len(signature.residual)
            frames.append(
                pd.DataFrame(
                    {
                        "round": np.int64(round_number),
                        "candidate": name,
                        "point": np.repeat(np.arange(n, dtype=np.int64), 3),
                        "axis": np.tile(["x", "y", "z"], n),
                        "residual_m": signature.residual.ravel(),
                        "effect_m": signature.effect.ravel(),
                    }
                )
            )
    columns = ["round", "candidate", "point", "axis", "residual_m", "effect_m"]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)


def signatures_of_round(frame: pd.DataFrame, round_number: int = 1) -> dict[str, Signature]:
    """The candidates' signatures of one round back from `signatures_frame`."""
    out = {}
    for name, part in frame[frame["round"] == round_number].groupby("candidate", sort=False):
        part = part.sort_values(["point", "axis"])
        out[name] = Signature(part["residual_m"].to_numpy().reshape(-1, 3), part["effect_m"].to_numpy().reshape(-1, 3))
    return out


def residuals_frame(residuals: dict[str, dict[str, np.ndarray]], rows: dict[str, np.ndarray]) -> pd.DataFrame:
    """Long table of the residuals before and after: when, set, point, x_m, y_m, z_m, and row:
    rows ({set: (n,)}) the sensor table's row of each point (so a pose can be found for it)."""
    frames = [
        pd.DataFrame(
            {
                "when": when,
                "set": set_name,
                "point": np.arange(len(r), dtype=np.int64),
                "x_m": r[:, 0],
                "y_m": r[:, 1],
                "z_m": r[:, 2],
                "row": np.asarray(rows[set_name], dtype=np.int64),
            }
        )
        for when, per_set in residuals.items()
        for set_name, r in per_set.items()
    ]
    return pd.concat(frames, ignore_index=True)


def residuals_of(frame: pd.DataFrame) -> dict[str, dict[str, np.ndarray]]:
    """`residuals_frame` back to {when: {set: (n, 3) m}}."""
    return {
        when: {
            s: part.sort_values("point")[["x_m", "y_m", "z_m"]].to_numpy()
            for s, part in per_when.groupby("set", sort=False)
        }
        for when, per_when in frame.groupby("when", sort=False)
    }

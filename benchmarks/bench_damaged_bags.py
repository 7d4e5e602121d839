"""Randomly damaged copies of a valid ROS 2 bag, read as `remaster import` reads one.

The bag: 10 sensor_msgs/msg/JointState messages on /joint_states and a std_msgs/msg/String on
/rosout after each (tests/campaigns/test_import_bag.py's `bag_bytes`), its chunks uncompressed or
zstd (rosbag2's default), written with CRCs (chunks and summary; mcap's writers leave the data
section's 0) or without. Each copy is damaged by `damaged`: 1 to 3 bytes flipped, cut off at a
random point, or a random range of 1 to 64 bytes zeroed. Per kind of bag, the counts of copies
`bags.read_joint_states` read the same as the valid bag ("same"), refused with an InputError naming
the file ("refused"), read to other joint states ("different": a change no CRC covers) or ended in
another exception ("other", by type: a traceback, which must stay 0).

Run from the repository root: nice python benchmarks/bench_damaged_bags.py [copies per kind] (default 250,
1,000 in all). Writes benchmarks/results/damaged_bags.json.
"""

from __future__ import annotations

import collections
import io
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from mcap.writer import CompressionType  # noqa: E402

from remaster.campaigns import bags  # noqa: E402
from remaster.errors import InputError  # noqa: E402
from tests.campaigns.test_import_bag import bag_bytes, damaged  # noqa: E402

KINDS = {
    "uncompressed, CRCs": (CompressionType.NONE, True),
    "zstd, CRCs": (CompressionType.ZSTD, True),
    "uncompressed, no CRC": (CompressionType.NONE, False),
    "zstd, no CRC": (CompressionType.ZSTD, False),
}
SEED = 7
OUT = REPO / "benchmarks" / "results" / "damaged_bags.json"


def run(copies: int) -> dict:
    rng = np.random.default_rng(SEED)
    q = rng.uniform(-1.0, 1.0, (10, 7))
    results = {}
    for kind, (compression, crcs) in KINDS.items():
        data = bag_bytes(q, compression, crcs)
        good = bags.read_joint_states(io.BytesIO(data), "/joint_states", "good.mcap")
        counts: collections.Counter = collections.Counter()
        for _ in range(copies):
            try:
                read = bags.read_joint_states(io.BytesIO(damaged(data, rng)), "/joint_states", "damaged.mcap")
            except InputError as error:
                counts["refused" if str(error).startswith("damaged.mcap: ") else "refused without the file"] += 1
            except Exception as error:  # noqa: BLE001 - counted: a traceback for the user
                counts[f"other: {type(error).__name__}"] += 1
            else:
                counts["same" if read == good else "different"] += 1
        results[kind] = {"bag_bytes": len(data), "copies": copies, **dict(sorted(counts.items()))}
    return results


def main(argv: list[str]) -> None:
    copies = int(argv[0]) if argv else 250
    start = time.perf_counter()
    results = run(copies)
    total = {key: sum(r.get(key, 0) for r in results.values()) for key in ("copies", "same", "refused", "different")}
    total["other"] = sum(v for r in results.values() for k, v in r.items() if k.startswith("other"))
    report = {"seed": SEED, "seconds": round(time.perf_counter() - start, 1), "total": total, "kinds": results}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main(sys.argv[1:])

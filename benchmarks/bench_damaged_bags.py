"""Randomly damaged copies of a valid ROS 2 bag, read as `remaster import` reads one.

The bag: 10 sensor_msgs/msg/JointState messages on /joint_states and a std_msgs/msg/String on
/rosout after each (`bag_bytes`, as tests/campaigns/test_import_bag.py writes them), its chunks uncompressed or
zstd (rosbag2's default), written with CRCs (chunks and summary; mcap's writers leave the data
section's 0) or without. Each copy is damaged by `damaged`: 1 to 3 bytes flipped, cut off at a
random point, or a random range of 1 to 64 bytes zeroed. The same joint states also as a sqlite3 bag
(ROS 2 Humble's default storage, written by rosbags; its .db3 file damaged the same way and read by
`bags.read_topics`, as `remaster import` reads one). Per kind of bag, the counts of copies read the
same as the valid bag ("same"), refused with an InputError naming the file ("refused"), read to other
joint states ("different": a change no CRC covers; sqlite3 has no CRCs) or ended in another exception
("other", by type: a traceback, which must stay 0).

Run from the repository root: nice python benchmarks/bench_damaged_bags.py [copies per kind] (default 250,
1,250 in all). Writes benchmarks/results/damaged_bags.json.
"""

from __future__ import annotations

import collections
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from mcap.writer import CompressionType  # noqa: E402
from mcap_ros2.writer import Writer  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as BagWriter  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from remaster.campaigns import bags  # noqa: E402
from remaster.errors import InputError  # noqa: E402

KINDS = {
    "uncompressed, CRCs": (CompressionType.NONE, True),
    "zstd, CRCs": (CompressionType.ZSTD, True),
    "uncompressed, no CRC": (CompressionType.NONE, False),
    "zstd, no CRC": (CompressionType.ZSTD, False),
}
SEED = 7
JOINT_STATE = "sensor_msgs/msg/JointState"
JOINT_STATE_MSGDEF = (
    "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n"
    + "=" * 80
    + "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
    + "=" * 80
    + "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
)
OUT = REPO / "benchmarks" / "results" / "damaged_bags.json"


def bag_bytes(q: np.ndarray, compression: CompressionType, crcs: bool) -> bytes:
    """A bag of a joint state (7 joints, 1 s apart) per row of q (n, 7) rad."""
    stream = io.BytesIO()
    writer = Writer(stream, compression=compression, enable_crcs=crcs)
    schema = writer.register_msgdef(JOINT_STATE, JOINT_STATE_MSGDEF)
    text = writer.register_msgdef("std_msgs/msg/String", "string data\n")
    for i, row in enumerate(q):
        stamp = 1_714_644_000_000_000_000 + i * 1_000_000_000
        message = {
            "header": {"stamp": {"sec": stamp // 10**9, "nanosec": 0}, "frame_id": ""},
            "name": [f"joint_a{j + 1}" for j in range(len(row))],
            "position": [float(p) for p in row],
            "velocity": [],
            "effort": [],
        }
        writer.write_message("/joint_states", schema, message, log_time=stamp)
        writer.write_message("/rosout", text, {"data": "moving"}, log_time=stamp + 1)
    writer.finish()
    return stream.getvalue()


def damaged(data: bytes, rng) -> bytes:
    """A randomly damaged copy of `data`: 1 to 3 bytes flipped, cut off at a random point, or a
    random range of 1 to 64 bytes zeroed (in turn, by rng)."""
    out = bytearray(data)
    kind = rng.integers(3)
    if kind == 0:
        for at in rng.integers(0, len(out), rng.integers(1, 4)):
            out[at] ^= int(rng.integers(1, 256))
        return bytes(out)
    if kind == 1:
        return bytes(out[: rng.integers(0, len(out))])
    start = int(rng.integers(0, len(out)))
    stop = min(len(out), start + int(rng.integers(1, 65)))
    out[start:stop] = bytes(stop - start)
    return bytes(out)


def sqlite_bag(q: np.ndarray, folder: Path) -> bytes:
    """The joint states of `bag_bytes` as a sqlite3 bag written by rosbags in `folder`: its .db3 bytes."""
    types = get_typestore(Stores.ROS2_HUMBLE)
    message_type = types.types[JOINT_STATE]
    with BagWriter(folder, version=8, storage_plugin=StoragePlugin.SQLITE3) as writer:
        states = writer.add_connection("/joint_states", JOINT_STATE, typestore=types)
        for i, row in enumerate(q):
            stamp = 1_714_644_000_000_000_000 + i * 1_000_000_000
            header = types.types["std_msgs/msg/Header"](
                stamp=types.types["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=0), frame_id=""
            )
            names = [f"joint_a{j + 1}" for j in range(len(row))]
            message = message_type(
                header=header, name=names, position=np.asarray(row), velocity=np.array([]), effort=np.array([])
            )
            writer.write(states, stamp, types.serialize_cdr(message, JOINT_STATE))
    return next(folder.glob("*.db3")).read_bytes()


def read_sqlite(data: bytes, path: Path) -> list:
    """The joint states `remaster import` reads from a sqlite3 bag of these bytes, written to `path`."""
    path.write_bytes(data)
    return bags.joint_states(bags.read_topics(path, {"/joint_states": (JOINT_STATE,)}, "damaged.db3")["/joint_states"])


def counted(good, read_copy, copies: int, rng) -> dict:
    """How `read_copy` (bytes -> joint states) fares on `copies` damaged copies of `good`'s bytes."""
    data, expected = good
    counts: collections.Counter = collections.Counter()
    for _ in range(copies):
        try:
            read = read_copy(damaged(data, rng))
        except InputError as error:
            counts["refused" if str(error).startswith("damaged.") else "refused without the file"] += 1
        except Exception as error:  # noqa: BLE001 - counted: a traceback for the user
            counts[f"other: {type(error).__name__}"] += 1
        else:
            counts["same" if read == expected else "different"] += 1
    return {"bag_bytes": len(data), "copies": copies, **dict(sorted(counts.items()))}


def run(copies: int) -> dict:
    rng = np.random.default_rng(SEED)
    q = rng.uniform(-1.0, 1.0, (10, 7))
    results = {}
    for kind, (compression, crcs) in KINDS.items():
        data = bag_bytes(q, compression, crcs)
        good = bags.read_joint_states(io.BytesIO(data), "/joint_states", "good.mcap")
        results[kind] = counted(
            (data, good),
            lambda copy: bags.read_joint_states(io.BytesIO(copy), "/joint_states", "damaged.mcap"),
            copies,
            rng,
        )
    with tempfile.TemporaryDirectory() as folder:
        data = sqlite_bag(q, Path(folder) / "bag")
        copy = Path(folder) / "damaged.db3"
        good = read_sqlite(data, copy)
        results["sqlite3"] = counted((data, good), lambda damaged_bytes: read_sqlite(damaged_bytes, copy), copies, rng)
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

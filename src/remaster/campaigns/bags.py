"""ROS 2 joint states from an MCAP bag (rosbag2's default storage), decoded with Foxglove's `mcap`
and `mcap-ros2-support` readers: no ROS installation needed.

`read_joint_states` decodes the sensor_msgs/msg/JointState messages of one topic from an open
binary stream (`folders.read_bag` opens the file; `importer.joint_state_export` makes them the
controller log of `remaster import`). Messages on other topics are not decoded. Every problem is an
InputError naming the bag: not an MCAP file, the topic absent (with the topics the bag has), another
message type on it, a message that cannot be decoded, no message at all.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import IO

from mcap.exceptions import McapError
from mcap.reader import McapReader, make_reader
from mcap.records import Channel, Schema
from mcap_ros2.decoder import DecoderFactory

from ..errors import InputError, listed

JOINT_STATE = "sensor_msgs/msg/JointState"
ROS2_ENCODING = ("cdr", "ros2msg")  # rosbag2's message and schema encodings
# what a damaged or foreign file raises inside the readers (their decompressors included; OSError: a
# seek before the start of a file too short for an MCAP footer)
_UNREADABLE = (McapError, struct.error, EOFError, OSError, ValueError, KeyError, IndexError, RuntimeError, MemoryError)


@dataclass(frozen=True)
class JointState:
    """One sensor_msgs/msg/JointState message as recorded. index: 1-based, in log-time order on its
    topic; log_time: when the bag logged it, stamp: its header.stamp, both in ns since the Unix
    epoch (UTC); name and position as in the message (position in rad for a revolute joint, m for
    a prismatic one: JointState's units, SI)."""

    index: int
    log_time: int
    stamp: int
    name: tuple[str, ...]
    position: tuple[float, ...]


def _channels(reader: McapReader) -> dict[int, tuple[Channel, Schema | None]]:
    """{channel id: (channel, schema)} of the bag: from its summary, or by reading it through
    when it has none (a bag written without one)."""
    summary = reader.get_summary()
    if summary is not None:
        return {i: (c, summary.schemas.get(c.schema_id)) for i, c in summary.channels.items()}
    return {message.channel_id: (channel, schema) for schema, channel, message in reader.iter_messages()}


def _check_topic(channels: Mapping[int, tuple[Channel, Schema | None]], topic: str, source: str) -> None:
    """InputError naming the bag and the topic unless the topic carries JointState messages in
    rosbag2's encoding (CDR, ros2msg schema)."""
    types = {c.topic: s.name if s is not None else "no schema" for c, s in channels.values()}
    on_topic = [(c, s) for c, s in channels.values() if c.topic == topic]
    if not on_topic:
        found = listed(f"{t} ({types[t]})" for t in sorted(types)) or "none"
        raise InputError(f"no such topic in the bag; its topics: {found}", file=source, key=topic)
    for channel, schema in on_topic:
        name = schema.name if schema is not None else "no schema"
        if name != JOINT_STATE:
            raise InputError(f"carries {name} messages, not {JOINT_STATE}", file=source, key=topic)
        if (channel.message_encoding, schema.encoding) != ROS2_ENCODING:
            raise InputError(
                f"{JOINT_STATE} encoded as {channel.message_encoding} with a {schema.encoding or 'no'} schema: "
                f"remaster reads rosbag2's {ROS2_ENCODING[0]} with {ROS2_ENCODING[1]} schemas",
                file=source,
                key=topic,
            )


def _joint_state(index: int, log_time: int, message) -> JointState:
    stamp = message.header.stamp
    return JointState(
        index=index,
        log_time=int(log_time),
        stamp=int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec),
        name=tuple(str(n) for n in message.name),
        position=tuple(float(p) for p in message.position),
    )


def read_joint_states(stream: IO[bytes], topic: str, source: str) -> list[JointState]:
    """The JointState messages on `topic` of the MCAP bag in `stream` (binary, seekable or not), in
    log-time order. `source` names the bag in errors (InputError): not an MCAP file or damaged, the
    topic absent (the message lists the bag's topics and their types), another type on it, no
    message on it."""
    states: list[JointState] = []
    decoding = False
    try:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        _check_topic(_channels(reader), topic, source)
        decoding = True
        for _, _, message, decoded in reader.iter_decoded_messages([topic], log_time_order=True):
            states.append(_joint_state(len(states) + 1, message.log_time, decoded))
    except InputError:
        raise
    except _UNREADABLE as exc:
        where = f" (decoding message {len(states) + 1} on {topic})" if decoding else ""
        detail = str(exc) or f"{type(exc).__name__} (empty, or cut off)"
        raise InputError(
            f"not a readable MCAP file{where}: {detail} (a bag cut off while recording: `mcap recover` repairs it)",
            file=source,
        ) from None
    if not states:
        raise InputError("no message on this topic in the bag", file=source, key=topic)
    return states

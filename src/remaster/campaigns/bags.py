"""ROS 2 bags (rosbag2) read without a ROS installation: joint states and sensor measurements.

Both of rosbag2's storages are read: MCAP (Jazzy's default) by Foxglove's `mcap` and
`mcap-ros2-support` readers, with every CRC the file carries checked (chunks, data section and
summary: a bag changed after writing is refused, not imported with a wrong value; rosbags' MCAP
reader checks the chunks' only, so MCAP stays with this reader, which benchmarks/bench_damaged_bags.py
holds to no traceback on 1,000 damaged bags), and sqlite3 (Humble's default, a .db3 file) by
`rosbags`, whose type store decodes the standard messages (sqlite3 bags carry no message
definitions, and no CRCs).

`read_topics` decodes the messages of the topics asked for, each checked to carry one of the
message types asked for; `joint_states` and `measurements` turn them into what `remaster import`
uses (`importer.joint_state_export`, `importer.measurement_export`). `read_joint_states` reads an
MCAP stream's joint states (the damaged-bag benchmark's entry). Messages on other topics are not
decoded. Every problem is an InputError naming the bag and the topic: not a bag, damaged, the topic
absent (with the topics the bag has), another message type on it, a message that cannot be decoded
(its index on the topic), no message at all.
"""

from __future__ import annotations

import contextlib
import io
import struct
import zlib
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mcap.exceptions import McapError
from mcap.reader import FOOTER_SIZE
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Schema
from mcap.stream_reader import MAGIC_SIZE, CRCValidationError, StreamReader, breakup_chunk
from mcap_ros2.decoder import DecoderFactory

from ..errors import InputError, listed

JOINT_STATE = "sensor_msgs/msg/JointState"
POINT_STAMPED = "geometry_msgs/msg/PointStamped"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
MEASUREMENTS = (POINT_STAMPED, POSE_STAMPED, TRANSFORM_STAMPED, TF_MESSAGE)  # a sensor topic's types
SQLITE_MAGIC = b"SQLite format 3\x00"  # the first bytes of a sqlite3 bag (.db3)
ROS2_ENCODING = ("cdr", "ros2msg")  # rosbag2's message and schema encodings
try:  # zstd chunks (rosbag2's default compression): its errors are no OSError or ValueError
    from zstandard import ZstdError

    _DECOMPRESSORS: tuple[type[Exception], ...] = (ZstdError,)
except ImportError:  # the reader refuses a zstd chunk then (UnsupportedCompressionError, an McapError)
    _DECOMPRESSORS = ()
# what a damaged or foreign file raises inside the readers (their decompressors included; OSError: a
# seek before the start of a file too short for an MCAP footer)
_UNREADABLE = (
    McapError,
    struct.error,
    EOFError,
    OSError,
    ValueError,
    KeyError,
    IndexError,
    RuntimeError,
    MemoryError,
    ArithmeticError,
    *_DECOMPRESSORS,
)


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


def _check_types(types: Mapping[str, str], wanted: Mapping[str, tuple[str, ...]], source: str) -> None:
    """InputError naming the bag and the topic unless each topic of `wanted` is among the bag's
    `types` (topic -> message type) with one of the types wanted."""
    for topic, accepted in wanted.items():
        if topic not in types:
            found = listed(f"{t} ({types[t]})" for t in sorted(types)) or "none"
            raise InputError(f"no such topic in the bag; its topics: {found}", file=source, key=topic)
        if types[topic] not in accepted:
            raise InputError(f"carries {types[topic]} messages, not {' or '.join(accepted)}", file=source, key=topic)


def _check_topic(
    channels: Mapping[int, tuple[Channel, Schema | None]], wanted: Mapping[str, tuple[str, ...]], source: str
) -> None:
    """`_check_types` of an MCAP bag's channels, then each wanted topic in rosbag2's encoding (CDR,
    ros2msg schema)."""
    types = {c.topic: s.name if s is not None else "no schema" for c, s in channels.values()}
    _check_types(types, wanted, source)
    for channel, schema in channels.values():
        if channel.topic in wanted and (channel.message_encoding, schema.encoding) != ROS2_ENCODING:
            raise InputError(
                f"{schema.name} encoded as {channel.message_encoding} with a {schema.encoding or 'no'} schema: "
                f"remaster reads rosbag2's {ROS2_ENCODING[0]} with {ROS2_ENCODING[1]} schemas",
                file=source,
                key=channel.topic,
            )


@dataclass(frozen=True)
class Measurement:
    """One sensor sample of a PointStamped, PoseStamped, TransformStamped or TFMessage transform.
    index: 1-based, in log-time order on its topic (a TFMessage's transforms share their message's);
    log_time and stamp (header.stamp) in ns since the Unix epoch (UTC); frame_id: the header's, the
    frame the position is in; xyz in m (ROS's unit); quaternion (w, x, y, z), None for a point."""

    index: int
    log_time: int
    stamp: int
    frame_id: str
    xyz: tuple[float, float, float]
    quaternion: tuple[float, float, float, float] | None


@dataclass(frozen=True)
class Recorded:
    """One decoded message of a topic: index 1-based in log-time order on the topic, log_time in ns
    (UTC), msgtype its type, message the decoded message (fields as attributes)."""

    index: int
    log_time: int
    msgtype: str
    message: Any


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def joint_states(recorded: Sequence[Recorded]) -> list[JointState]:
    """The JointStates of a topic's decoded sensor_msgs/msg/JointState messages."""
    return [
        JointState(
            index=r.index,
            log_time=r.log_time,
            stamp=_ns(r.message.header.stamp),
            name=tuple(str(n) for n in r.message.name),
            position=tuple(float(p) for p in r.message.position),
        )
        for r in recorded
    ]


def measurements(recorded: Sequence[Recorded], child_frame: str | None = None) -> list[Measurement]:
    """The Measurements of a topic's decoded MEASUREMENTS messages: a TFMessage's transforms (and a
    TransformStamped) whose child_frame_id is `child_frame` (all when None)."""

    def sample(r: Recorded, header, position, rotation) -> Measurement:
        quaternion = None if rotation is None else tuple(float(getattr(rotation, a)) for a in "wxyz")
        return Measurement(
            index=r.index,
            log_time=r.log_time,
            stamp=_ns(header.stamp),
            frame_id=str(header.frame_id),
            xyz=tuple(float(getattr(position, a)) for a in "xyz"),
            quaternion=quaternion,
        )

    out = []
    for r in recorded:
        m = r.message
        if r.msgtype == POINT_STAMPED:
            out.append(sample(r, m.header, m.point, None))
        elif r.msgtype == POSE_STAMPED:
            out.append(sample(r, m.header, m.pose.position, m.pose.orientation))
        else:  # a TransformStamped, or a TFMessage's list of them
            for t in m.transforms if r.msgtype == TF_MESSAGE else [m]:
                if child_frame is None or t.child_frame_id == child_frame:
                    out.append(sample(r, t.header, t.transform.translation, t.transform.rotation))
    return out


def _read_through(
    stream: IO[bytes], topics: Collection[str]
) -> tuple[dict[int, tuple[Channel, Schema | None]], list, list[str]]:
    """One pass through the whole bag with the CRCs it carries checked: each chunk's (of its
    uncompressed records, before they are parsed) and the data section's as the reader goes, then
    the summary's (seekable streams; the mcap readers do not check it). Returns {channel id:
    (channel, schema)} of the data section, the messages on `topics` [(channel id, Message)] in file
    order (the summary adds only channels registered without a message), and the CRCs checked ("chunks", "data section", "summary"; none when the bag was written
    without CRCs, a CRC of 0: its records are then only parsed)."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, tuple[Channel, Schema | None]] = {}
    messages: list = []
    checked: set[str] = set()

    def take(record) -> None:
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            if record.schema_id and record.schema_id not in schemas:
                raise McapError(f"channel {record.id} ({record.topic}) names schema {record.schema_id}, not in the bag")
            channels[record.id] = (record, schemas.get(record.schema_id))
        elif isinstance(record, Message):
            if record.channel_id not in channels:
                raise McapError(f"a message on channel {record.channel_id}, not in the bag")
            if channels[record.channel_id][0].topic in topics:
                messages.append((record.channel_id, record))

    data_section = True  # after DataEnd: the summary, whose copies of the data section's records are not used
    footer = None
    for record in StreamReader(stream, validate_crcs=True, emit_chunks=True).records:
        if isinstance(record, DataEnd):
            data_section = False
            if record.data_section_crc:
                checked.add("data section")  # checked by StreamReader as it read DataEnd
        elif isinstance(record, Footer):
            footer = record
        elif data_section and isinstance(record, Chunk):
            if record.uncompressed_crc:
                checked.add("chunks")
            for inner in breakup_chunk(record, validate_crc=True):
                take(inner)
        elif data_section:
            take(record)
        elif isinstance(record, Schema | Channel) and record.id not in (
            schemas if isinstance(record, Schema) else channels
        ):
            take(record)  # a channel registered without a message is in the summary only
    if footer is not None and footer.summary_crc and stream.seekable():
        _check_summary_crc(stream, footer)
        checked.add("summary")
    return channels, messages, sorted(checked)


def _check_summary_crc(stream: IO[bytes], footer: Footer) -> None:
    """CRCValidationError unless the summary section and the footer's fields before its CRC (up to
    the end of the file but the CRC and the closing magic) have the footer's CRC."""
    end = stream.seek(0, io.SEEK_END) - MAGIC_SIZE - 4
    footer_start = stream.seek(0, io.SEEK_END) - MAGIC_SIZE - FOOTER_SIZE
    start = footer.summary_start or footer_start
    if not 0 < start <= footer_start:
        raise McapError(f"the footer's summary start {start} is outside the file")
    stream.seek(start)
    crc, left = 0, end - start
    while left > 0:
        block = stream.read(min(left, 1 << 20))
        if not block:
            raise McapError("the file ended inside its summary")
        crc, left = zlib.crc32(block, crc), left - len(block)
    if crc != footer.summary_crc:
        raise CRCValidationError(expected=footer.summary_crc, actual=crc, record=footer)


def _decode(
    channels: Mapping[int, tuple[Channel, Schema | None]], messages: list, source: str
) -> dict[str, list[Recorded]]:
    """The decoded `messages` [(channel id, Message)], per topic in log-time order. The schema and
    the messages are a damaged bag's when their CRCs were 0 (not written): the ROS 2 decoder (a
    vendored rosidl parser, then CDR) raises any exception then, each an InputError naming the bag,
    the topic and the message."""
    factory = DecoderFactory()
    decoders = {}
    used = {channel_id for channel_id, _ in messages}
    for i, (channel, schema) in channels.items():
        if i in used:
            try:
                decoders[i] = factory.decoder_for(channel.message_encoding, schema)
            except Exception as exc:  # noqa: BLE001 - any failure of a third-party parser on bad bytes
                raise InputError(
                    f"its {schema.name} schema does not parse: {type(exc).__name__}: {exc}",
                    file=source,
                    key=channel.topic,
                ) from None
    out: dict[str, list[Recorded]] = {}
    for channel_id, message in sorted(messages, key=lambda m: m[1].log_time):
        channel, schema = channels[channel_id]
        on_topic = out.setdefault(channel.topic, [])
        try:
            decoded = decoders[channel_id](message.data)
        except Exception as exc:  # noqa: BLE001 - as above
            raise InputError(
                f"message {len(on_topic) + 1} does not decode as {schema.name}: {type(exc).__name__}: {exc}",
                file=source,
                key=channel.topic,
            ) from None
        on_topic.append(Recorded(len(on_topic) + 1, int(message.log_time), schema.name, decoded))
    return out


def _read_mcap(stream: IO[bytes], wanted: Mapping[str, tuple[str, ...]], source: str) -> dict[str, list[Recorded]]:
    """The messages of the topics `wanted` (topic -> the types accepted) of the MCAP bag in `stream`
    (binary, seekable or not). The whole bag is read once with its CRCs checked (`_read_through`):
    a bag whose bytes changed after writing is refused, not imported with a wrong value."""
    try:
        channels, messages, _ = _read_through(stream, wanted)
        _check_topic(channels, wanted, source)
        with contextlib.redirect_stderr(io.StringIO()):  # the schema parser prints what it cannot parse
            return _decode(channels, messages, source)
    except InputError:
        raise
    except CRCValidationError as exc:
        raise InputError(
            f"damaged: the CRC of its {_crc_of(exc)} does not match its bytes (expected {exc.expected:#010x}, "
            f"computed {exc.actual:#010x}): the bag changed after it was written (a bad copy or disk); "
            "re-copy it from the recording",
            file=source,
        ) from None
    except _UNREADABLE as exc:
        detail = str(exc) or f"{type(exc).__name__} (empty, or cut off)"
        raise InputError(
            f"not a readable MCAP file: {type(exc).__name__}: {detail} "
            "(a bag cut off while recording: `mcap recover` repairs it)",
            file=source,
        ) from None


def _read_sqlite(path: Path, wanted: Mapping[str, tuple[str, ...]], source: str) -> dict[str, list[Recorded]]:
    """The messages of the topics `wanted` of a sqlite3 bag (.db3), read and decoded by rosbags with
    the ROS 2 Humble type store (a sqlite3 bag names its types but carries no definitions)."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    out: dict[str, list[Recorded]] = {}
    try:
        with Reader(path) as reader:
            _check_types({c.topic: c.msgtype for c in reader.connections}, wanted, source)
            connections = [c for c in reader.connections if c.topic in wanted]
            for connection, log_time, raw in reader.messages(connections=connections):
                on_topic = out.setdefault(connection.topic, [])
                try:
                    decoded = typestore.deserialize_cdr(raw, connection.msgtype)
                except Exception as exc:  # noqa: BLE001 - any failure of the CDR decoder on bad bytes
                    raise InputError(
                        f"message {len(on_topic) + 1} does not decode as {connection.msgtype}: "
                        f"{type(exc).__name__}: {exc}",
                        file=source,
                        key=connection.topic,
                    ) from None
                on_topic.append(Recorded(len(on_topic) + 1, int(log_time), connection.msgtype, decoded))
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags' and sqlite3's errors on a damaged database
        raise InputError(f"not a readable sqlite3 bag: {type(exc).__name__}: {exc}", file=source) from None
    # rosbags yields a sqlite3 bag's messages in timestamp order already; sorted for certainty
    return {t: sorted(r, key=lambda m: m.log_time) for t, r in out.items()}


def read_topics(path: Path, wanted: Mapping[str, tuple[str, ...]], source: str) -> dict[str, list[Recorded]]:
    """The messages of the topics `wanted` (topic -> the message types accepted on it) of the bag
    file at `path`, MCAP or sqlite3 (told by its first bytes), per topic in log-time order.
    InputError naming the bag (`source`): not a bag, damaged, a topic absent or carrying another
    type, a message that does not decode, no message on a topic."""
    with path.open("rb") as stream:
        sqlite = stream.read(len(SQLITE_MAGIC)) == SQLITE_MAGIC
        if not sqlite:
            stream.seek(0)
            read = _read_mcap(stream, wanted, source)
    if sqlite:
        read = _read_sqlite(path, wanted, source)
    for topic in wanted:
        if not read.get(topic):
            raise InputError("no message on this topic in the bag", file=source, key=topic)
    return read


def read_joint_states(stream: IO[bytes], topic: str, source: str) -> list[JointState]:
    """The JointState messages on `topic` of the MCAP bag in `stream` (binary, seekable or not), in
    log-time order (file order among equal times), its CRCs checked; errors as `read_topics`'."""
    states = joint_states(_read_mcap(stream, {topic: (JOINT_STATE,)}, source).get(topic, []))
    if not states:
        raise InputError("no message on this topic in the bag", file=source, key=topic)
    return states


def _crc_of(exc: CRCValidationError) -> str:
    record = exc.record
    if isinstance(record, DataEnd):
        return "data section (DataEnd)"
    if isinstance(record, Footer):
        return "summary section (footer)"
    return (
        f"{type(record).__name__.lower()} at log times {record.message_start_time}..{record.message_end_time} ns"
        if isinstance(record, Chunk)
        else type(record).__name__
    )

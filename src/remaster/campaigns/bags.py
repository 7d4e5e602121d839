"""ROS 2 joint states from an MCAP bag (rosbag2's default storage), decoded with Foxglove's `mcap`
and `mcap-ros2-support` readers: no ROS installation needed.

`read_joint_states` decodes the sensor_msgs/msg/JointState messages of one topic from an open
binary stream (`folders.read_bag` opens the file; `importer.joint_state_export` makes them the
controller log of `remaster import`). Messages on other topics are not decoded. Every problem is an
InputError naming the bag: not an MCAP file, the topic absent (with the topics the bag has), another
message type on it, a message that cannot be decoded, no message at all.
"""

from __future__ import annotations

import contextlib
import io
import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import IO

from mcap.exceptions import McapError
from mcap.reader import FOOTER_SIZE
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Schema
from mcap.stream_reader import MAGIC_SIZE, CRCValidationError, StreamReader, breakup_chunk
from mcap_ros2.decoder import DecoderFactory

from ..errors import InputError, listed

JOINT_STATE = "sensor_msgs/msg/JointState"
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


def _read_through(stream: IO[bytes], topic: str) -> tuple[dict[int, tuple[Channel, Schema | None]], list, list[str]]:
    """One pass through the whole bag with the CRCs it carries checked: each chunk's (of its
    uncompressed records, before they are parsed) and the data section's as the reader goes, then
    the summary's (seekable streams; the mcap readers do not check it). Returns {channel id:
    (channel, schema)} of the data section, the messages on `topic` [(channel id, Message)] in file
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
            if channels[record.channel_id][0].topic == topic:
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
    channels: Mapping[int, tuple[Channel, Schema | None]], messages: list, topic: str, source: str
) -> list[JointState]:
    """The JointStates of `messages` [(channel id, Message)] in log-time order. The schema and the
    messages are a damaged bag's when their CRCs were 0 (not written): the ROS 2 decoder (a vendored
    rosidl parser, then CDR) raises any exception then, each an InputError naming the bag, the
    topic and the message."""
    factory = DecoderFactory()
    decoders = {}
    for i, (channel, schema) in channels.items():
        if channel.topic == topic:
            try:
                decoders[i] = factory.decoder_for(channel.message_encoding, schema)
            except Exception as exc:  # noqa: BLE001 - any failure of a third-party parser on bad bytes
                raise InputError(
                    f"its {JOINT_STATE} schema does not parse: {type(exc).__name__}: {exc}", file=source, key=topic
                ) from None
    states: list[JointState] = []
    for channel_id, message in sorted(messages, key=lambda m: m[1].log_time):
        try:
            states.append(_joint_state(len(states) + 1, message.log_time, decoders[channel_id](message.data)))
        except Exception as exc:  # noqa: BLE001 - as above
            raise InputError(
                f"message {len(states) + 1} does not decode as {JOINT_STATE}: {type(exc).__name__}: {exc}",
                file=source,
                key=topic,
            ) from None
    return states


def read_joint_states(stream: IO[bytes], topic: str, source: str) -> list[JointState]:
    """The JointState messages on `topic` of the MCAP bag in `stream` (binary, seekable or not), in
    log-time order (file order among equal times). The whole bag is read once with its CRCs
    checked (`_read_through`): a bag whose bytes changed after writing is refused, not imported
    with a wrong value. `source` names the bag in errors (InputError): not an MCAP file, damaged (a
    CRC that does not match, a record that does not parse, a message that does not decode: with
    its index on the topic), the topic absent (the message lists the bag's topics and their types),
    another type on it, no message on it."""
    try:
        channels, messages, _ = _read_through(stream, topic)
        _check_topic(channels, topic, source)
        with contextlib.redirect_stderr(io.StringIO()):  # the schema parser prints what it cannot parse
            states = _decode(channels, messages, topic, source)
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

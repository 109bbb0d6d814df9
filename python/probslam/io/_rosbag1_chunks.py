"""A ROS 1 bag (format 2.0) read by walking its chunks, for bags whose index records are damaged.

The index (connection records and chunk infos at ``index_pos``, index-data records after each
chunk) only repeats what the chunks hold: every connection record and every message record is
inside a chunk. ``rosbags``' reader trusts the index and stops at the first inconsistency (the
CCNY laser_scan_matcher demo bag states wrong index-data lengths); walking the chunks reads such a
bag in full. Messages are deserialised with a ``rosbags`` typestore built from the connections'
own message definitions.

Record layout (wiki.ros.org/Bags/Format/2.0): ``uint32 header_len``, header fields (each
``uint32 len`` then ``name=value``), ``uint32 data_len``, data. Opcodes: 0x02 message data, 0x03
bag header, 0x04 index data, 0x05 chunk (``compression`` none / bz2 / lz4, ``size``), 0x06 chunk
info, 0x07 connection (its data is a second header: topic, type, md5sum, message_definition).
"""

from __future__ import annotations

import bz2
import struct
from dataclasses import dataclass
from typing import Dict, Iterator, List, Tuple

OP_MESSAGE = 0x02
OP_INDEX_DATA = 0x04
OP_CHUNK = 0x05
OP_CONNECTION = 0x07

#: The largest record (header or data) accepted, bytes: a corrupt length field would otherwise
#: ask for gigabytes. rosbag's own chunks are 768 KiB by default; 1 GiB leaves room for any real one.
MAX_RECORD_BYTES = 1 << 30


@dataclass
class Connection:
    """A connection record: its id, topic, normalised message type and definition."""

    id: int
    topic: str
    msgtype: str
    msgdef: str


def normalize_msgtype(name: str) -> str:
    """``pkg/Type`` (ROS 1) as ``pkg/msg/Type`` (the ROS 2 spelling rosbags uses)."""
    parts = [p for p in name.split("/") if p]
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return "/".join(parts)


def _fields(header: bytes) -> Dict[str, bytes]:
    """The ``name=value`` fields of a record header; a malformed one raises ValueError."""
    out: Dict[str, bytes] = {}
    pos = 0
    while pos < len(header):
        if pos + 4 > len(header):
            raise ValueError("header field length cut off")
        (size,) = struct.unpack_from("<I", header, pos)
        pos += 4
        field = header[pos:pos + size]
        if len(field) != size or b"=" not in field:
            raise ValueError("malformed header field")
        name, value = field.split(b"=", 1)
        out[name.decode("ascii", "replace")] = value
        pos += size
    return out


def _record_at(data: bytes, pos: int) -> Tuple[Dict[str, bytes], int, int]:
    """(header fields, data start, data end) of the record at ``pos``; ValueError when its
    lengths run past the end or its header is malformed."""
    if pos + 4 > len(data):
        raise ValueError(f"record cut off at byte {pos}")
    (hlen,) = struct.unpack_from("<I", data, pos)
    if hlen > MAX_RECORD_BYTES or pos + 8 + hlen > len(data):
        raise ValueError(f"record at byte {pos}: header length {hlen} runs past the end")
    header = _fields(data[pos + 4:pos + 4 + hlen])
    (dlen,) = struct.unpack_from("<I", data, pos + 4 + hlen)
    start = pos + 8 + hlen
    if header.get("op") == bytes([OP_INDEX_DATA]) and header.get("ver") == struct.pack("<I", 1) \
            and len(header.get("count", b"")) == 4:
        # An index-data record (version 1) holds count entries of 12 bytes (time, offset): its
        # data length is that, whatever the record states (the CCNY demo bag states 20 per entry).
        dlen = 12 * struct.unpack("<I", header["count"])[0]
    if dlen > MAX_RECORD_BYTES or start + dlen > len(data):
        raise ValueError(f"record at byte {pos}: data length {dlen} runs past the end")
    return header, start, start + dlen


def _records(data: bytes, start: int) -> Iterator[Tuple[Dict[str, bytes], bytes]]:
    """(header fields, data) of the records in ``data`` from ``start``; stops with ValueError at
    the first record whose lengths run past the end or whose header is malformed."""
    pos = start
    while pos < len(data):
        header, begin, end = _record_at(data, pos)
        yield header, data[begin:end]
        pos = end


def _next_chunk(data: bytes, pos: int) -> int:
    """The start of the first chunk record after byte ``pos`` that parses, or -1."""
    marker = struct.pack("<I", 4) + b"op=" + bytes([OP_CHUNK])
    hit = data.find(marker, pos)
    while hit >= 0:
        # The record starts a few fields before its op field: try each start whose header
        # would contain the hit (a chunk's header has three short fields).
        for begin in range(max(pos, hit - 128), hit):
            try:
                header, _, _ = _record_at(data, begin)
            except (ValueError, struct.error):
                continue
            if header.get("op") == bytes([OP_CHUNK]):
                return begin
        hit = data.find(marker, hit + 1)
    return -1


def _top_records(data: bytes, start: int, problems: List[str]) -> Iterator[Tuple[Dict[str, bytes], bytes]]:
    """The file's top-level records; where one cannot be read, the walk resumes at the next
    chunk record found after it (a problem listed)."""
    pos = start
    while pos < len(data):
        try:
            header, begin, end = _record_at(data, pos)
        except (ValueError, struct.error) as exc:
            resume = _next_chunk(data, pos + 1)
            problems.append(f"unreadable records skipped ({exc}; "
                            + (f"resumed at byte {resume})" if resume >= 0 else "no chunk after it)"))
            if resume < 0:
                return
            pos = resume
            continue
        yield header, data[begin:end]
        pos = end


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    """The chunk's records; at most ``size`` bytes (what its header states) are expanded, so a
    crafted chunk cannot expand to gigabytes, and a different length is an error."""
    if size > MAX_RECORD_BYTES:
        raise ValueError(f"chunk size {size} exceeds MAX_RECORD_BYTES")
    if compression == "none":
        out = bytes(data)
    elif compression == "bz2":
        out = bz2.BZ2Decompressor().decompress(data, max_length=size + 1)
    elif compression == "lz4":
        import lz4.frame  # a dependency of rosbags

        out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=size + 1)
    else:
        raise ValueError(f"unknown chunk compression {compression!r}")
    if len(out) != size:
        raise ValueError(f"chunk holds {len(out)}{'+' if len(out) > size else ''} bytes, its header states {size}")
    return out


@dataclass
class ChunkWalk:
    """What walking the chunks found: the connections, the messages (connection id, record
    time in ns, raw bytes) in file order, and what could not be read (reasons)."""

    connections: Dict[int, Connection]
    messages: List[Tuple[int, int, bytes]]
    problems: List[str]


def walk_chunks(raw) -> ChunkWalk:
    """Every connection and message record of the chunks of a ROS 1 bag held in ``raw`` (bytes
    or a read-only mmap). A chunk
    that cannot be decompressed is skipped (a problem listed); a record cut off ends the walk of
    its chunk (or of the file) there. A file that is not a ROS 1 2.0 bag raises ValueError."""
    magic = b"#ROSBAG V2.0\n"
    if raw[:len(magic)] != magic:
        raise ValueError("not a ROS 1 bag (format 2.0): the file does not start with '#ROSBAG V2.0'")
    connections: Dict[int, Connection] = {}
    messages: List[Tuple[int, int, bytes]] = []
    problems: List[str] = []
    for header, data in _top_records(raw, len(magic), problems):
        if header.get("op") != bytes([OP_CHUNK]):
            continue
        try:
            compression = header["compression"].decode("ascii", "replace")
            (size,) = struct.unpack("<I", header["size"])
            chunk = _decompress(compression, data, size)
        except (KeyError, ValueError, OSError, EOFError, RuntimeError, struct.error) as exc:
            problems.append(f"a chunk could not be read ({exc})")
            continue
        try:
            for h, d in _records(chunk, 0):
                op = h.get("op")
                if op == bytes([OP_CONNECTION]):
                    (cid,) = struct.unpack("<I", h["conn"])
                    info = _fields(d)
                    connections[cid] = Connection(
                        cid, h["topic"].decode("utf-8", "replace"),
                        normalize_msgtype(info["type"].decode("utf-8", "replace")),
                        info.get("message_definition", b"").decode("utf-8", "replace"))
                elif op == bytes([OP_MESSAGE]):
                    (cid,) = struct.unpack("<I", h["conn"])
                    sec, nsec = struct.unpack("<II", h["time"])
                    messages.append((cid, sec * 1_000_000_000 + nsec, d))
        except (KeyError, ValueError, struct.error) as exc:
            problems.append(f"a chunk's records stop early ({exc})")
    return ChunkWalk(connections, messages, problems)

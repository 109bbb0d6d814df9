"""ROS bags in: ROS 1 ``.bag``, ROS 2 folders (sqlite3 ``.db3`` or ``.mcap`` storage), read into
the ``CarmenLog`` shape that ``run_slam`` and ``map_laser_log`` take (``rosbag_writer`` writes
them). Built on the ``rosbags`` package (pure Python, no ROS installation; ``pip install rosbags``
or ``pip install 'probslam[ros]'``), imported only when a bag is read or written.

Frames: the robot pose is the transform ``odom_frame -> base_frame`` (from ``nav_msgs/Odometry``
messages, or composed along ``tf`` through any intermediate frames), the laser pose that pose
composed with the offset ``base_frame -> laser frame`` (``tf_static``, or ``laser_offset``).
Poses are projected on the plane: ``(x, y, yaw)``.
"""

from __future__ import annotations

import math
import mmap
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from ..geometry import compose, interpolate
from ._files import file_path
from .carmen import CarmenLog, LaserScans, Odometry

PathLike = Union[str, "os.PathLike[str]"]

SCAN_TYPES = ("sensor_msgs/msg/LaserScan",)
ODOMETRY_TYPES = ("nav_msgs/msg/Odometry",)
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")
POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
              "nav_msgs/msg/Odometry")
#: The file names of a bag: a ROS 1 file, a ROS 2 storage file (read through its folder).
BAG_SUFFIXES = (".bag", ".db3", ".mcap")

#: The most skipped messages a ``RosbagLog`` lists with their reasons (all are counted), as
#: ``io.carmen.MAX_REPORTED_LINES`` for a CARMEN log.
MAX_REPORTED_MESSAGES = 10


INSTALL_HINT = "reading or writing ROS bags needs the rosbags package: pip install rosbags (or 'probslam[ros]')"


def _rosbags():
    """The rosbags modules used here; ImportError saying how to install them."""
    try:
        from rosbags import highlevel, rosbag1, rosbag2, typesys  # noqa: F401
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    import rosbags

    return rosbags


@dataclass
class RosbagLog(CarmenLog):
    """A bag as ``read_rosbag`` reads it: a ``CarmenLog`` (scans, odometry, skipped counts; its
    ``skipped_lines`` are message numbers in reading order) and what it was read from.

    path; scan_topic; pose_source, where the robot poses came from ("odometry TOPIC", "tf
    ODOM->BASE", "poses TOPIC" or "none"); laser_offset (x, y, theta) and laser_offset_source
    ("tf_static", "given" or "none"); topics {name: message type}; backward_stamps, scans
    stamped earlier than the scan recorded before them (kept in recording order unless
    ``sort_by_stamp``); laser_upside_down, when tf_static mounts the laser upside down (its beam
    angles are then mirrored: ``start_angles`` and ``angular_resolutions`` negated); index_note,
    set when a ROS 1 bag's index could not be used and its chunks
    were walked instead.
    """

    path: str = ""
    scan_topic: str = ""
    pose_source: str = "none"
    laser_offset: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    laser_offset_source: str = "none"
    topics: Dict[str, str] = field(default_factory=dict)
    backward_stamps: int = 0
    index_note: str = ""
    laser_upside_down: bool = False

    def describe(self) -> str:
        """One line: topics and sources read, counts skipped."""
        parts = [f"scans from {self.scan_topic}",
                 f"poses from {self.pose_source}" if self.pose_source != "none"
                 else "no odometry, tf or pose topic (poses all zero)"]
        if self.laser_offset_source != "none":
            x, y, t = self.laser_offset
            parts.append(f"laser offset ({x:g}, {y:g}, {t:g}) from {self.laser_offset_source}"
                         + (", upside down (beam angles mirrored)" if self.laser_upside_down else ""))
        if self.skipped_rows:
            parts.append(f"{self.skipped_rows} messages skipped")
        if self.backward_stamps:
            parts.append(f"{self.backward_stamps} scans stamped before the previous one")
        if self.index_note:
            parts.append(self.index_note)
        return "; ".join(parts)


def is_bag(path: PathLike) -> bool:
    """Whether ``path`` names a bag: a ``.bag`` / ``.db3`` / ``.mcap`` file or a folder with a
    ROS 2 ``metadata.yaml``."""
    path = os.fsdecode(path)
    if os.path.isdir(path):
        return os.path.isfile(os.path.join(path, "metadata.yaml"))
    return path.lower().endswith(BAG_SUFFIXES)


# --- message sources ---------------------------------------------------------------------------

@dataclass
class _Source:
    """An opened bag: topics {name: type}, and messages(topics) yielding (topic, record time ns,
    decode()) in recording order, where decode() raises on a message that cannot be read."""

    topics: Dict[str, str]
    messages: Callable[[Sequence[str]], Iterator[Tuple[str, int, Callable[[], Any]]]]
    index_note: str = ""
    problems: List[str] = field(default_factory=list)
    close: Callable[[], None] = lambda: None
    #: a ROS 1 bag read through its index: when reading stops, walking the chunks may read on
    chunks_may_read_on: bool = False


class _ReadingStopped(Exception):
    """The source stopped yielding messages (a damaged chunk, a truncated file)."""


def _ros2_folder(path: str) -> str:
    """The ROS 2 bag folder of ``path`` (a folder, or a .db3 / .mcap file inside one)."""
    if os.path.isdir(path):
        if not os.path.isfile(os.path.join(path, "metadata.yaml")):
            raise ValueError(f"{path}: a folder without metadata.yaml is not a ROS 2 bag")
        return path
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isfile(os.path.join(folder, "metadata.yaml")):
        raise ValueError(f"{path}: a ROS 2 storage file is read with its bag folder's metadata.yaml, "
                         f"and {folder} has none")
    return folder


def _open_any(path: str) -> _Source:
    """The bag read through rosbags' AnyReader (its index for ROS 1)."""
    from pathlib import Path

    from rosbags.highlevel import AnyReader

    target = Path(path if path.lower().endswith(".bag") else _ros2_folder(path))
    reader = AnyReader([target], default_typestore=_ros2_standard_messages())
    reader.open()
    try:
        topics = {name: info.msgtype for name, info in reader.topics.items()}
    except BaseException:
        reader.close()
        raise

    def messages(names: Sequence[str]):
        conns = [c for c in reader.connections if c.topic in names]
        if conns:
            for conn, t, raw in reader.messages(connections=conns):
                yield conn.topic, t, (lambda raw=raw, typ=conn.msgtype: reader.deserialize(raw, typ))

    return _Source(topics, messages, close=reader.close, chunks_may_read_on=target.suffix.lower() == ".bag")


#: The message definitions a ROS 2 bag without its own (recorded before Iron: metadata.yaml
#: version 5 and below, Foxy / Galactic / Humble) is read with: the distribution's standard
#: messages. Those read here (sensor_msgs/LaserScan, nav_msgs/Odometry, tf2_msgs/TFMessage,
#: geometry_msgs/PoseStamped and PoseWithCovarianceStamped) are the same in Foxy, Galactic and
#: Humble, so one store serves them all. A bag that stores its definitions is read with those.
ROS2_DEFAULT_DISTRIBUTION = "ros2_humble"


def _ros2_standard_messages():
    """rosbags' typestore of ``ROS2_DEFAULT_DISTRIBUTION``'s standard messages."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores(ROS2_DEFAULT_DISTRIBUTION))


#: Files of a ROS 2 bag folder that rosbags opens: each must be a regular file (a FIFO blocks
#: the reader forever, a device never ends).
_ROS2_FILES = ("metadata.yaml", ".db3", ".mcap", ".zstd")


def _require_regular_bag_files(path: str) -> None:
    """ValueError when ``path``, or a file its ROS 2 folder would be read from, is not a regular
    file (a FIFO, a device, a socket)."""
    from ._files import require_regular_file

    if not os.path.isdir(path):
        require_regular_file(path)
        if path.lower().endswith(".bag"):
            return
    folder = path if os.path.isdir(path) else os.path.dirname(os.path.abspath(path))
    with os.scandir(folder) as entries:
        for entry in entries:
            if entry.name.lower().endswith(_ROS2_FILES) and not entry.is_dir():
                require_regular_file(entry.path)


def _typestore_for(definitions: Dict[str, str]):
    """A typestore holding the bag's own message definitions (ROS 1 text); old bags define their
    header as ``roslib/Header``, which the text names ``Header``: std_msgs/Header is given too."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    types: Dict[str, Any] = {}
    for msgtype, text in definitions.items():
        types.update(get_types_from_msg(text, msgtype))
    if "std_msgs/msg/Header" not in types:
        types["std_msgs/msg/Header"] = types.get("roslib/msg/Header") or \
            get_typestore(Stores.ROS1_NOETIC).fielddefs["std_msgs/msg/Header"]
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    return store


def _open_chunks(path: str, note: str) -> _Source:
    """A ROS 1 bag read by walking its chunks (its index unusable)."""
    from ._rosbag1_chunks import walk_chunks
    from ._files import require_regular_file

    require_regular_file(path)
    with open(path, "rb") as f:
        if os.fstat(f.fileno()).st_size == 0:
            raise ValueError(f"{path}: empty file")
        # Mapped, not read: the walk touches each chunk once, and a bag may be gigabytes.
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as raw:
            walk = walk_chunks(raw)
    conns = walk.connections
    try:
        store = _typestore_for({c.msgtype: c.msgdef for c in conns.values()})
    except Exception as exc:  # noqa: BLE001 - rosbags' parser errors have no common base
        raise ValueError(f"{path}: the bag's message definitions cannot be read: {type(exc).__name__}: {exc}") \
            from None
    topics = {c.topic: c.msgtype for c in conns.values()}
    # Recording order: the chunks are walked in file order; a stable sort on the record time
    # puts a message written late (out of order) back in its place.
    ordered = sorted((m for m in walk.messages if m[0] in conns), key=lambda m: m[1])

    def messages(names: Sequence[str]):
        for cid, t, raw in ordered:
            conn = conns[cid]
            if conn.topic in names:
                yield conn.topic, t, (lambda raw=raw, typ=conn.msgtype: store.deserialize_ros1(raw, typ))

    return _Source(topics, messages, note, list(walk.problems))


def _open(path: str) -> _Source:
    _rosbags()
    if not os.path.exists(path):
        raise FileNotFoundError(f"path: no such file or folder: {path!r}")
    _require_regular_bag_files(path)
    try:
        return _open_any(path)
    except FileNotFoundError:
        raise
    except (AssertionError, Exception) as exc:  # noqa: BLE001 - rosbags' errors have no common base
        if not path.lower().endswith(".bag"):
            raise ValueError(f"{path}: cannot read the bag: {type(exc).__name__}: {exc}") from None
        reason = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
        return _open_chunks(path, f"index unreadable by rosbags ({reason}): read by walking its chunks")


# --- geometry ----------------------------------------------------------------------------------

def _yaw(q) -> float:
    """Heading of a quaternion (x, y, z, w) projected on the plane."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _rotation(q) -> np.ndarray:
    """The 3 x 3 rotation of a quaternion (x, y, z, w), normalised."""
    x, y, z, w = q.x, q.y, q.z, q.w
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not (n > 0 and math.isfinite(n)):
        raise ValueError("quaternion of zero or non-finite length")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _stamp(header) -> float:
    """A header's stamp in seconds, the nearest double to sec + nanosec / 10^9 (integer division
    rounds once: a CARMEN log's 0.204947 s written to a bag reads back as 0.204947, not
    0.20494700000000002)."""
    return (int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)) / 1_000_000_000


def _frame(name: str) -> str:
    """A tf frame id without its leading slash (ROS 1 bags often have one, tf2 none)."""
    return name.lstrip("/")


@dataclass
class _Track:
    """Poses (N, 3) at timestamps (N,), sorted by time; velocities (N, 2) where known."""

    timestamps: np.ndarray
    poses: np.ndarray
    velocities: np.ndarray

    @staticmethod
    def of(rows: List[Tuple[float, float, float, float, float, float]]) -> "_Track":
        data = np.array(sorted(rows, key=lambda r: r[0]), dtype=float).reshape(-1, 6)
        return _Track(data[:, 0], data[:, 1:4], data[:, 4:6])

    def at(self, times: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """(poses at the times inside the track's span, mask of those times)."""
        if len(self.timestamps) == 0:
            return np.zeros((0, 3)), np.zeros(len(times), bool)
        inside = (times >= self.timestamps[0]) & (times <= self.timestamps[-1])
        return interpolate(self.timestamps, self.poses, times[inside]), inside


class _TfTree:
    """tf edges parent -> child: each dynamic one a track, each static one a pose."""

    def __init__(self) -> None:
        self.dynamic: Dict[Tuple[str, str], List[Tuple[float, float, float, float, float, float]]] = {}
        self.static: Dict[Tuple[str, str], np.ndarray] = {}
        #: each edge's rotation (the first message's), 3 x 3: the laser's mounting (upside down?)
        self.rotation: Dict[Tuple[str, str], np.ndarray] = {}
        self.parent: Dict[str, str] = {}

    def add(self, msg, static: bool) -> None:
        for tr in msg.transforms:
            parent, child = _frame(tr.header.frame_id), _frame(tr.child_frame_id)
            t = tr.transform.translation
            pose = (t.x, t.y, _yaw(tr.transform.rotation))
            if not all(math.isfinite(v) for v in pose):
                raise ValueError(f"transform {parent} -> {child} is not finite")
            self.parent[child] = parent
            if static or (parent, child) not in self.rotation:
                self.rotation[(parent, child)] = _rotation(tr.transform.rotation)
            if static:
                self.static[(parent, child)] = np.array(pose)
            else:
                self.dynamic.setdefault((parent, child), []).append((_stamp(tr.header), *pose, math.nan, math.nan))

    def root(self, frame: str) -> Optional[str]:
        """The top of the tree above ``frame`` (None when tf does not know it)."""
        if frame not in self.parent:
            return None
        seen = {frame}
        while frame in self.parent and self.parent[frame] not in seen:
            frame = self.parent[frame]
            seen.add(frame)
        return frame

    def frames(self) -> List[str]:
        return sorted(set(self.parent) | set(self.parent.values()))

    def chain(self, top: str, bottom: str) -> Optional[List[Tuple[str, str]]]:
        """The edges from ``top`` down to ``bottom``, or None when bottom is not below top."""
        edges: List[Tuple[str, str]] = []
        node = bottom
        seen = set()
        while node != top:
            if node not in self.parent or node in seen:
                return None
            seen.add(node)
            edges.append((self.parent[node], node))
            node = self.parent[node]
        return edges[::-1]

    def is_static(self, edge: Tuple[str, str]) -> bool:
        """Whether the edge never moves: from tf_static, or on /tf with one value throughout (ROS 1
        bags from before tf_static repeat their fixed transforms there)."""
        if edge not in self.dynamic:
            return edge in self.static
        rows = self.dynamic[edge]
        return all(r[1:4] == rows[0][1:4] for r in rows)

    def constant(self, edge: Tuple[str, str]) -> np.ndarray:
        """The value of a static edge."""
        return self.static[edge] if edge not in self.dynamic else np.array(self.dynamic[edge][0][1:4])

    def evaluate(self, edges: List[Tuple[str, str]], times: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """The composed transform of ``edges`` at ``times`` and the mask of the times every
        dynamic edge covers (each interpolated within its own messages)."""
        poses = np.zeros((len(times), 3))
        ok = np.ones(len(times), bool)
        for edge in edges:
            if self.is_static(edge):
                poses = compose(poses, self.constant(edge))
                continue
            track = _Track.of(self.dynamic[edge])
            step = np.zeros((len(times), 3))
            at, inside = track.at(times)
            step[inside] = at
            ok &= inside
            poses = compose(poses, step)
        return poses, ok


# --- reading -----------------------------------------------------------------------------------

def _pick(topics: Dict[str, str], types: Sequence[str], named: Optional[str], option: str,
          what: str, required: bool) -> Optional[str]:
    """The topic named (checked: present, of one of ``types``), or the only candidate."""
    if named is not None:
        if not isinstance(named, str):
            raise TypeError(f"{option}: expected a topic name (str), got {type(named).__name__}")
        if named not in topics:
            raise ValueError(f"{option}: no topic {named!r} in the bag (topics: "
                             f"{', '.join(f'{t} [{m}]' for t, m in sorted(topics.items())) or 'none'})")
        if topics[named] not in types:
            raise ValueError(f"{option}: topic {named!r} has message type {topics[named]}, "
                             f"expected {' or '.join(types)}")
        return named
    found = sorted(t for t, m in topics.items() if m in types)
    if len(found) > 1:
        raise ValueError(f"several {what} topics: {', '.join(found)}; name one with {option}")
    if not found and required:
        raise ValueError(f"no {what} topic ({' or '.join(types)}) in the bag (topics: "
                         f"{', '.join(f'{t} [{m}]' for t, m in sorted(topics.items())) or 'none'})")
    return found[0] if found else None


def _offset_arg(value) -> Optional[np.ndarray]:
    if value is None:
        return None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError("laser_offset: expected (x, y, theta) numbers") from None
    if arr.shape != (3,):
        raise ValueError(f"laser_offset: expected (x, y, theta), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("laser_offset: must contain only finite values")
    from .._core import wrap_angle

    arr = arr.copy()
    arr[2] = wrap_angle(float(arr[2]))
    return arr


class _Skips:
    """Messages skipped: counted, the first MAX_REPORTED_MESSAGES listed with their reasons."""

    def __init__(self) -> None:
        self.count = 0
        self.numbers: List[int] = []
        self.reasons: List[str] = []

    def add(self, number: int, reason: str) -> None:
        self.count += 1
        if len(self.numbers) < MAX_REPORTED_MESSAGES:
            self.numbers.append(number)
            self.reasons.append(reason)


def _scan_fields(msg) -> Tuple[np.ndarray, float, float, float, float, float]:
    """(float32 ranges, start angle, increment, range_min, range_max, stamp) of a LaserScan;
    ValueError for fields that cannot describe a scan."""
    ranges = np.asarray(msg.ranges, dtype=np.float32)
    values = (float(msg.range_min), float(msg.range_max), float(msg.angle_min), float(msg.angle_increment))
    if not all(math.isfinite(v) for v in values) or values[1] <= 0 or ranges.ndim != 1 or ranges.size == 0:
        raise ValueError(f"bad LaserScan fields (range_min {msg.range_min}, range_max {msg.range_max}, angle_min "
                         f"{msg.angle_min}, angle_increment {msg.angle_increment}, {ranges.size} ranges)")
    return ranges, values[2], values[3], values[0], values[1], _stamp(msg.header)


def widen_float32(values: np.ndarray) -> np.ndarray:
    """float32 values as the float64 of their shortest decimal form (numpy's repr of a float32):
    a reading of 1.07 m stored as float32 comes back as 1.07, not 1.0700000524520874. LaserScan
    ranges are float32, and the sensors (and CARMEN logs) report them in mm or cm: this recovers
    the reported value exactly, where a plain cast adds up to 3e-8 of relative noise."""
    values = np.asarray(values, dtype=np.float32)
    unique, inverse = np.unique(values, return_inverse=True)  # far fewer distinct readings than beams
    return unique.astype(str).astype(float)[inverse].reshape(values.shape)


def _no_return(ranges: np.ndarray, num_beams: np.ndarray, range_min: np.ndarray,
               range_max: np.ndarray) -> np.ndarray:
    """Ranges (S, B), NaN-padded after each row's num_beams, with NaN, +inf and readings beyond
    range_max set to range_max: no return, the value a CARMEN log holds for it
    (``LaserScans.no_return_range`` and ``run_slam`` read it from ``max_ranges``); -inf and readings
    below range_min (too close, or an error: REP 117) set to NaN, no reading, as the padding."""
    beam = np.arange(ranges.shape[1])[None, :] < num_beams[:, None]
    out = ranges.copy()
    with np.errstate(invalid="ignore"):
        none = beam & (np.isnan(ranges) | (ranges > range_max[:, None]))
        close = beam & (ranges < range_min[:, None])
    out[none] = np.broadcast_to(range_max[:, None], out.shape)[none]
    out[close] = np.nan
    return out


def read_rosbag(path: PathLike, *, scan_topic: Optional[str] = None, odom_topic: Optional[str] = None,
                pose_topic: Optional[str] = None, odom_frame: Optional[str] = None,
                base_frame: Optional[str] = None, laser_offset: Optional[Sequence[float]] = None,
                sort_by_stamp: bool = False) -> RosbagLog:
    """Read the laser scans of a ROS bag, located by odometry, tf or a pose topic.

    path: a ROS 1 ``.bag``, a ROS 2 bag folder, or a ``.db3`` / ``.mcap`` file in one. Topics
    are found by type when there is one candidate: ``sensor_msgs/LaserScan`` (scan_topic),
    ``nav_msgs/Odometry`` (odom_topic). ``pose_topic`` (a ``PoseStamped``,
    ``PoseWithCovarianceStamped`` or ``Odometry`` topic of corrected poses, e.g. for
    ``map_laser_log``) replaces odometry as the source of the robot poses. Without an odometry
    topic, the robot pose is ``odom_frame -> base_frame`` along ``tf`` (composed through any
    intermediate frames; frame ids with or without a leading slash); odom_frame defaults to
    "odom" (else the root of the laser frame's tree), base_frame to the frame below which the
    tree down to the laser is static. The laser offset is ``base_frame -> the scan's frame_id``
    from ``tf_static`` (or ``/tf``), unless ``laser_offset=(x, y, theta)`` is given; none found:
    the laser sits at the robot pose. A bag with neither odometry nor tf gives scans whose
    poses are all zero: ``run_slam`` then runs on scan matching alone.

    Poses are interpolated (``eval.interpolate_poses``) to each scan's header stamp; a scan
    outside the poses' time span is skipped. Scans keep their recording order (as ``rosbag
    play`` delivers them); those stamped before the previous scan are counted in
    ``backward_stamps`` and, with ``sort_by_stamp``, put in stamp order. Ranges: see the
    returned ``LaserScans``; NaN, inf and readings beyond range_max are the no-return value
    range_max (``max_ranges``), readings below range_min NaN.

    Errors: rosbags not installed: ImportError saying ``pip install rosbags``. A missing path:
    FileNotFoundError. A topic named and absent or of another type, several candidates for one
    option, no scan topic or a scan topic without a readable message: ValueError naming the
    topic or the option. Messages that cannot be decoded (or hold non-finite fields) are
    skipped, counted in ``skipped_rows`` with the first numbers and reasons listed, and one
    warning names them; a ROS 1 bag whose index is damaged is read by walking its chunks
    (``index_note``). A path (or a file of its ROS 2 folder) that is not a regular file (a FIFO,
    a device): ValueError. A ROS 2 bag recorded without message definitions (before Iron) is read
    with the standard messages of ``ROS2_DEFAULT_DISTRIBUTION``.
    """
    path = file_path(path)
    offset = _offset_arg(laser_offset)
    for name, value in (("odom_frame", odom_frame), ("base_frame", base_frame)):
        if value is not None and not isinstance(value, str):
            raise TypeError(f"{name}: expected a frame id (str), got {type(value).__name__}")
    source = _open(path)
    try:
        return _read(source, path, scan_topic, odom_topic, pose_topic, odom_frame, base_frame, offset,
                     bool(sort_by_stamp))
    except _ReadingStopped as stopped:
        note = f"rosbags stopped reading ({stopped}): read by walking its chunks"
    finally:
        source.close()
    # A ROS 1 bag whose index opened but whose messages could not all be read through it.
    return _read(_open_chunks(path, note), path, scan_topic, odom_topic, pose_topic, odom_frame, base_frame,
                 offset, bool(sort_by_stamp))


def _poses_of_track(track: _Track, stamps: np.ndarray, name: str):
    """(robot poses at the stamps, mask of the stamps inside the track, Odometry, source name)."""
    robot = np.zeros((len(stamps), 3))
    at, usable = track.at(stamps)
    robot[usable] = at
    return robot, usable, Odometry(track.poses, track.velocities, track.timestamps), name


def _poses_of_tf(tree: _TfTree, stamps: np.ndarray, laser_frame: str, odom_frame: Optional[str],
                 base: Optional[str]):
    """(robot poses, mask, Odometry, source name, base frame) from tf: ``odom_frame`` ("odom",
    else the root above the laser) to ``base`` (by default the frame below the last moving edge
    on the way down to the laser). No tf: zero poses, source "none"."""
    robot = np.zeros((len(stamps), 3))
    usable = np.ones(len(stamps), bool)
    odometry = Odometry(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0))
    top = _frame(odom_frame) if odom_frame is not None else ("odom" if "odom" in tree.frames() else
                                                           tree.root(laser_frame))
    named = base is not None
    if base is None and top is not None:
        moving = [e for e in tree.chain(top, laser_frame) or [] if not tree.is_static(e)]
        base = moving[-1][1] if moving else None
    chain = tree.chain(top, base) if top is not None and base is not None else None
    if chain is None and (odom_frame is not None or named):
        raise ValueError(f"{'base_frame' if named else 'odom_frame'}: no tf chain from {top} to {base} "
                         f"(frames: {', '.join(tree.frames()) or 'none'})")
    if not chain or all(tree.is_static(e) for e in chain):
        return robot, usable, odometry, "none", base
    robot, usable = tree.evaluate(chain, stamps)
    times = np.unique([row[0] for e in chain if not tree.is_static(e) for row in tree.dynamic[e]])
    poses, ok = tree.evaluate(chain, times)
    odometry = Odometry(poses[ok], np.full((int(ok.sum()), 2), np.nan), times[ok])
    return robot, usable, odometry, f"tf {top}->{base}", base


def _static_offset(tree: _TfTree, base: Optional[str], laser_frame: str) -> Tuple[np.ndarray, str, bool]:
    """(the laser's pose in the base frame, "tf_static", upside down), or (zeros, "none", False)
    when tf has no fixed chain from the base to the laser. Base unknown (odometry without a
    child frame): the top of the fixed chain above the laser. Upside down: the laser's z axis
    points down in the base frame (a scanner mounted under a plate), so its beams sweep the
    other way round: the reader mirrors their angles."""
    if base is None:
        node = laser_frame
        while node in tree.parent and tree.is_static((tree.parent[node], node)) and tree.parent[node] != laser_frame:
            node = tree.parent[node]
        base = node
    if base != laser_frame:
        chain = tree.chain(base, laser_frame)
        if chain and all(tree.is_static(e) for e in chain):
            rotation = np.eye(3)
            for edge in chain:
                rotation = rotation @ tree.rotation[edge]
            offset = tree.evaluate(chain, np.zeros(1))[0][0]
            # The planar heading of the laser's x axis (the per-edge yaws compose to it only when
            # every edge is a rotation about z).
            offset[2] = math.atan2(rotation[1, 0], rotation[0, 0])
            return offset, "tf_static", bool(rotation[2, 2] < 0)
    return np.zeros(3), "none", False


def _read(source: _Source, path: str, scan_topic, odom_topic, pose_topic, odom_frame, base_frame,
          offset, sort_by_stamp) -> RosbagLog:
    topics = source.topics
    scan_topic = _pick(topics, SCAN_TYPES, scan_topic, "scan_topic", "sensor_msgs/LaserScan", True)
    pose_topic = _pick(topics, POSE_TYPES, pose_topic, "pose_topic", "pose", False) if pose_topic else None
    if odom_topic is not None or pose_topic is None:
        odom_topic = _pick(topics, ODOMETRY_TYPES, odom_topic, "odom_topic", "nav_msgs/Odometry", False)
    if pose_topic is not None:
        odom_topic = None
    tf_topics = [t for t, m in topics.items() if m in TF_TYPES]
    wanted = [scan_topic] + [t for t in (odom_topic, pose_topic) if t] + tf_topics

    skips = _Skips()
    scans: List[Tuple[np.ndarray, float, float, float, float, str]] = []
    track_rows: List[Tuple[float, float, float, float, float, float]] = []
    tree = _TfTree()
    child_frames: List[str] = []
    stream = source.messages(wanted)
    number = 0
    while True:
        try:
            topic, _, decode = next(stream)
        except StopIteration:
            break
        except Exception as exc:  # noqa: BLE001 - a damaged chunk or a truncated file
            reason = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
            if source.chunks_may_read_on:
                raise _ReadingStopped(reason) from None
            skips.add(-1, f"reading stopped after message {number}: {reason}")
            break
        number += 1
        try:
            msg = decode()
            if topic == scan_topic:
                ranges, start, step, lo, hi, stamp = _scan_fields(msg)
                scans.append((ranges, start, step, lo, hi, stamp, _frame(msg.header.frame_id)))
            elif topic in (odom_topic, pose_topic):
                pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
                vel = (msg.twist.twist.linear.x, msg.twist.twist.angular.z) if hasattr(msg, "twist") \
                    else (math.nan, math.nan)
                row = (_stamp(msg.header), pose.position.x, pose.position.y, _yaw(pose.orientation), *vel)
                if not all(math.isfinite(v) for v in row[:4]):
                    raise ValueError("pose is not finite")
                track_rows.append(row)
                if hasattr(msg, "child_frame_id") and msg.child_frame_id and not child_frames:
                    child_frames.append(_frame(msg.child_frame_id))
            else:
                tree.add(msg, static=topic.rstrip("/").endswith("tf_static"))
        except Exception as exc:  # noqa: BLE001 - a message that cannot be decoded or used
            skips.add(number, f"{topic}: {type(exc).__name__}: {exc}".rstrip(": "))
    for problem in source.problems:
        skips.add(-1, problem)
    if not scans:
        extra = f" ({skips.count} of its messages could not be read)" if skips.count else ""
        raise ValueError(f"{path}: topic {scan_topic} holds no readable LaserScan{extra}")

    stamps = np.array([s[5] for s in scans])
    backward = int(np.count_nonzero(np.diff(stamps) < 0))
    order = np.argsort(stamps, kind="stable") if sort_by_stamp else np.arange(len(scans))
    stamps = stamps[order]
    scans = [scans[i] for i in order]

    laser_frame = scans[0][6]
    base = _frame(base_frame) if base_frame is not None else None
    if track_rows:
        robot, usable, odometry, source_name = _poses_of_track(_Track.of(track_rows), stamps,
                                                               f"{'poses' if pose_topic else 'odometry'} "
                                                               f"{pose_topic or odom_topic}")
        if base is None and child_frames:
            base = child_frames[0]
    else:
        robot, usable, odometry, source_name, base = _poses_of_tf(tree, stamps, laser_frame, odom_frame, base)
    if offset is not None:
        found_offset, offset_source, upside_down = offset, "given", False
    else:
        found_offset, offset_source, upside_down = _static_offset(tree, base, laser_frame)
    mirror = -1.0 if upside_down else 1.0
    laser = compose(robot, found_offset)

    for i in np.flatnonzero(~usable):
        skips.add(-1, f"{scan_topic}: scan stamped {stamps[i]:.9f} outside the poses' time span "
                      f"({source_name})")
    keep = np.flatnonzero(usable)
    if keep.size == 0:
        raise ValueError(f"{path}: no scan of {scan_topic} lies within the time span of its poses "
                         f"({source_name})")
    num_beams = np.array([len(scans[i][0]) for i in keep])
    # Bounded sizes, as the CARMEN reader: scans so much wider than the rest that padding every
    # scan to them would hold more than 4x the beams read are skipped (counted).
    wide = 0
    while num_beams.size > 1 and num_beams.size * int(num_beams.max()) > 4 * int(num_beams.sum()):
        widest = int(np.argmax(num_beams))
        keep, num_beams = np.delete(keep, widest), np.delete(num_beams, widest)
        wide += 1
    raw = np.full((keep.size, int(num_beams.max())), np.nan, dtype=np.float32)
    for row, i in enumerate(keep):
        raw[row, :num_beams[row]] = scans[i][0]
    range_max = widen_float32([scans[i][4] for i in keep])
    ranges = _no_return(widen_float32(raw), num_beams, widen_float32([scans[i][3] for i in keep]), range_max)
    laser_scans = LaserScans(
        ranges=ranges, laser_poses=laser[keep], robot_poses=robot[keep],
        # Angles stay the float32 values the message holds: unlike ranges in mm, an increment
        # such as 2 pi / 1024 has no short decimal form to recover.
        start_angles=mirror * np.array([scans[i][1] for i in keep]),
        angular_resolutions=mirror * np.array([scans[i][2] for i in keep]), max_ranges=range_max,
        num_beams=num_beams, timestamps=stamps[keep])
    log = RosbagLog(laser_scans, odometry, {}, wide, skips.count, skips.numbers, skips.reasons,
                    path=path, scan_topic=scan_topic, pose_source=source_name,
                    laser_offset=tuple(float(v) for v in found_offset), laser_offset_source=offset_source,
                    laser_upside_down=upside_down,
                    topics=dict(topics), backward_stamps=backward, index_note=source.index_note)
    if skips.count:
        first = f"{'message ' + str(skips.numbers[0]) + ': ' if skips.numbers[0] > 0 else ''}{skips.reasons[0]}"
        warnings.warn(f"{path}: skipped {skips.count} message{'s' if skips.count > 1 else ''} (first: {first})",
                      stacklevel=3)
    return log

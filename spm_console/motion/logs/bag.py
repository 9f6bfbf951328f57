"""A run folder as a ROS 2 bag: ``metadata.yaml`` beside ``run.mcap``, and the QoS each topic
is offered with, as rosbag2 records them (``ros2 bag info RUN/``, ``ros2 bag play RUN/``).

rosbag2 opens a bag by its folder's ``metadata.yaml`` (``rosbag2_bagfile_information``): the
storage plugin (``mcap``), the files, the time span and every topic with its type, its
serialization (``cdr``), the QoS profiles it was offered with and its message count. Written
here in the format's version 5, the one ROS 2 Humble writes and every later release reads
(the QoS profiles as one YAML text with rmw's enum values, as in Humble's recordings). The
same QoS text sits in each MCAP channel's metadata (``offered_qos_profiles``), where rosbag2's
MCAP storage keeps it; ``ros2 bag play`` offers it again: reliable, and transient-local for
``/robot_description`` so that a node started after the replay began still receives the URDF
(volatile otherwise, as a live publisher of those topics offers them).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from spm_console.errors import BadInputError
from spm_console.safe_io import write_text_atomic

METADATA_NAME = "metadata.yaml"
VERSION = 5
"""rosbag2's metadata format: 5 is ROS 2 Humble's (per-file entries; no custom data, type
hashes or distribution, which later versions add and read as absent)."""
STORAGE = "mcap"
LATCHED = frozenset({"/robot_description"})
"""Topics offered transient-local: one message at the start that a late subscriber needs."""

# rmw's QoS enum values (rmw/types.h), as rosbag2 wrote them up to version 8 of its metadata
_HISTORY_UNKNOWN = 3  # a recording knows the offer, not the publisher's history: rosbag2 says 3
_RELIABLE = 1
_TRANSIENT_LOCAL, _VOLATILE = 1, 2
_LIVELINESS_AUTOMATIC = 1
_INFINITE = (9_223_372_036, 854_775_807)
"""rmw's infinite duration (2⁶³ − 1 ns) as seconds and nanoseconds: no deadline, lifespan or
lease."""


def offered_qos(topic: str) -> str:
    """The QoS profiles ``topic`` is offered with, as rosbag2's metadata text (a YAML list of
    one profile): reliable; transient-local for :data:`LATCHED`, else volatile."""
    durability = _TRANSIENT_LOCAL if topic in LATCHED else _VOLATILE
    sec, nsec = _INFINITE
    time = f"\n    sec: {sec}\n    nsec: {nsec}"
    return (f"- history: {_HISTORY_UNKNOWN}\n  depth: 0\n  reliability: {_RELIABLE}\n"
            f"  durability: {durability}\n  deadline:{time}\n  lifespan:{time}\n"
            f"  liveliness: {_LIVELINESS_AUTOMATIC}\n  liveliness_lease_duration:{time}\n"
            f"  avoid_ros_namespace_conventions: false")


@dataclass
class TopicCount:
    """One topic of the bag: its ROS type and how many messages it carries."""

    name: str
    type: str
    count: int = 0


@dataclass
class BagContents:
    """What an MCAP file holds, counted as it is written: the topics in the order they first
    appear, and the earliest and latest log time (ns since the epoch)."""

    topics: dict[str, TopicCount] = field(default_factory=dict)
    first_ns: int | None = None
    last_ns: int | None = None

    def add(self, topic: str, msgtype: str, log_ns: int) -> None:
        self.topics.setdefault(topic, TopicCount(topic, msgtype)).count += 1
        self.first_ns = log_ns if self.first_ns is None else min(self.first_ns, log_ns)
        self.last_ns = log_ns if self.last_ns is None else max(self.last_ns, log_ns)

    @property
    def message_count(self) -> int:
        return sum(t.count for t in self.topics.values())


def _text(s: str) -> str:
    """``s`` as a YAML double-quoted scalar (JSON's string syntax is YAML's)."""
    return json.dumps(s)


def metadata_yaml(contents: BagContents, file_name: str) -> str:
    """``metadata.yaml`` of a bag of one MCAP file, ``file_name`` in the same folder."""
    start = contents.first_ns or 0
    span = (contents.last_ns or 0) - start  # rosbag2's duration: first to last message
    total = contents.message_count
    out = ["rosbag2_bagfile_information:", f"  version: {VERSION}",
           f"  storage_identifier: {STORAGE}",
           "  duration:", f"    nanoseconds: {span}",
           "  starting_time:", f"    nanoseconds_since_epoch: {start}",
           f"  message_count: {total}", "  topics_with_message_count:"]
    for t in contents.topics.values():
        out += ["    - topic_metadata:", f"        name: {_text(t.name)}",
                f"        type: {_text(t.type)}", "        serialization_format: cdr",
                f"        offered_qos_profiles: {_text(offered_qos(t.name))}",
                f"      message_count: {t.count}"]
    out += ['  compression_format: ""', '  compression_mode: ""',
            "  relative_file_paths:", f"    - {_text(file_name)}",
            "  files:", f"    - path: {_text(file_name)}",
            "      starting_time:", f"        nanoseconds_since_epoch: {start}",
            "      duration:", f"        nanoseconds: {span}",
            f"      message_count: {total}"]
    return "\n".join(out) + "\n"


def write_metadata(mcap: Path, contents: BagContents) -> Path:
    """Write ``metadata.yaml`` beside ``mcap`` (replaced atomically), which makes their folder
    a rosbag2 bag of that one file; its path."""
    path = mcap.parent / METADATA_NAME
    write_text_atomic(path, metadata_yaml(contents, mcap.name), BadInputError)
    return path

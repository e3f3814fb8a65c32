"""Message type names of ROS 1 bags recorded before ROS Electric, mapped to today's.

Old ROS 1 releases kept a few standard types in ``roslib``: ``roslib/Header`` (moved to
``std_msgs/Header`` by REP 100, ROS Electric) and ``roslib/Clock``, ``roslib/Log`` (moved to
``rosgraph_msgs`` before it). Bags recorded then carry those names in their connections' message
definitions (a ``MSG: roslib/Header`` section after ``Header header``), which rosbags cannot
resolve ("Type 'std_msgs/msg/Header' is unknown"). The definitions are the same, so the MD5 sums
are too; rosbag and genpy read such bags by renaming (genpy's ``dynamic.py`` replaces
``roslib/Header`` with ``std_msgs/Header``), and so does :func:`modern_connection`.
"""

from __future__ import annotations

import re

from rosbags.interfaces import Connection, MessageDefinition
from rosbags.typesys.msg import normalize_msgtype

__all__ = ["LEGACY_TYPES", "modern_connection", "modern_names"]

LEGACY_TYPES: dict[str, str] = {
    "roslib/Header": "std_msgs/Header",
    "roslib/Clock": "rosgraph_msgs/Clock",
    "roslib/Log": "rosgraph_msgs/Log",
}
"""Pre-Electric type names and their names since."""
_LEGACY = re.compile(r"(?<![\w/])roslib/(?:Header|Clock|Log)\b")


def modern_names(text: str) -> str:
    """``text`` (a message definition or a type name) with the pre-Electric names replaced."""
    return _LEGACY.sub(lambda match: LEGACY_TYPES[match.group(0)], text)


def modern_connection(connection: Connection) -> Connection:
    """``connection`` with today's type names in its type and message definition (itself when
    it has none of the old names)."""
    msgdef = modern_names(connection.msgdef.data)
    old_type = connection.msgtype.replace("/msg/", "/")
    msgtype = normalize_msgtype(LEGACY_TYPES.get(old_type, old_type))
    if msgdef == connection.msgdef.data and msgtype == connection.msgtype:
        return connection
    return connection._replace(
        msgtype=msgtype, msgdef=MessageDefinition(connection.msgdef.format, msgdef)
    )

"""ROS 2 conversions of maps: ``nav_msgs`` OccupancyGrid and MapMetaData."""

from __future__ import annotations

from typing import Any

import numpy as np
from nav_msgs.msg import MapMetaData as RosMapMetaData
from nav_msgs.msg import OccupancyGrid as RosOccupancyGrid

from agents_core import messages as m
from agents_core.errors import TypeValidationError

from .base import INT32_MAX, NS_PER_S, RosConversion, as_numpy, f32, header_from_ros, header_to_ros, seq
from .geometry import pose_from_ros, pose_to_ros

__all__ = ["CONVERSIONS"]


def _grid_to_ros(v: m.OccupancyGridMsg) -> RosOccupancyGrid:
    out = RosOccupancyGrid()
    header_to_ros(v.header, out.header)
    out.info.map_load_time = out.header.stamp
    out.info.resolution = v.resolution
    out.info.height, out.info.width = (int(s) for s in v.data.shape)
    out.info.origin = pose_to_ros(v.origin)
    out.data = seq("b", v.data.reshape(-1), np.int8)
    return out


def _grid_from_ros(msg: RosOccupancyGrid) -> m.OccupancyGridMsg:
    cells = as_numpy(msg.data, np.int8)
    height, width = int(msg.info.height), int(msg.info.width)
    if cells.size != height * width:
        raise TypeValidationError(f"occupancy grid data has {cells.size} cells; {width}x{height} needs "
                                  f"{height * width}")
    header = header_from_ros(msg.header)
    return m.OccupancyGridMsg(data=cells.reshape(height, width), resolution=f32(msg.info.resolution),
                              origin=pose_from_ros(msg.info.origin, header), header=header)


def _time_to_ros(stamp_ns: int, out: Any) -> None:
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    if sec > INT32_MAX:
        raise TypeValidationError(f"stamp {stamp_ns} ns does not fit ROS 2 time (int32 seconds)")
    out.sec, out.nanosec = sec, nanosec


def _map_info_to_ros(v: m.MapMetaDataMsg) -> RosMapMetaData:
    out = RosMapMetaData(resolution=float(v.resolution), width=int(v.width), height=int(v.height),
                         origin=pose_to_ros(v.origin))
    _time_to_ros(v.map_load_time_ns, out.map_load_time)
    return out


def _map_info_from_ros(msg: RosMapMetaData) -> m.MapMetaDataMsg:
    t = msg.map_load_time
    if t.sec < 0 or t.nanosec >= NS_PER_S:
        raise TypeValidationError(f"map_load_time ({t.sec} s, {t.nanosec} ns) is not a valid stamp")
    return m.MapMetaDataMsg(resolution=f32(msg.resolution), width=int(msg.width), height=int(msg.height),
                            origin=pose_from_ros(msg.origin), map_load_time_ns=t.sec * NS_PER_S + t.nanosec)


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "OccupancyGrid": RosConversion(RosOccupancyGrid, _grid_to_ros, _grid_from_ros),
    "MapMetaData": RosConversion(RosMapMetaData, _map_info_to_ros, _map_info_from_ros),
}

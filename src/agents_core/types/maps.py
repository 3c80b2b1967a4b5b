"""Grid maps: the occupancy grid and its geometry (map metadata)."""

from __future__ import annotations

from typing import Any

from attrs import define, field

from ..support.lazy_numpy import np, npt
from .base import SupportedType
from .fields import Header, Message, header_field, instance_of, int_in, is_number, named, to_array, unstamped, wire
from .geometry import PoseMsg

__all__ = ["MapMetaData", "MapMetaDataMsg", "OccupancyGrid", "OccupancyGridMsg"]


def _data(value: Any) -> npt.NDArray[np.int8]:
    return to_array(value, np.int8, (None, None), "data")


@named
@define(eq=False)
class OccupancyGridMsg(Message):
    """A 2-D grid map: int8 cells (-1 unknown, 0..100 occupancy), ``resolution`` m/cell."""

    data: npt.NDArray[np.int8] = field(factory=lambda: np.zeros((0, 0), np.int8),
                                       converter=_data, metadata=wire("HxW |i1 (-1 unknown, 0..100)"))
    resolution: float = field(default=0.05, validator=is_number, metadata=wire("float (m/cell)"))
    origin: PoseMsg = field(factory=PoseMsg, validator=instance_of(PoseMsg))
    header: Header = header_field()


@named
@define(eq=False)
class MapMetaDataMsg(Message):
    """A grid map's geometry: ``resolution`` (m/cell), ``width`` x ``height`` cells, the ``origin`` pose of
    cell (0, 0), and when the map was loaded (``map_load_time_ns``, ns since the epoch)."""

    resolution: float = field(default=0.05, validator=is_number, metadata=wire("float (m/cell)"))
    width: int = field(default=0, validator=int_in(0, 2**32 - 1))
    height: int = field(default=0, validator=int_in(0, 2**32 - 1))
    origin: PoseMsg = field(factory=PoseMsg, validator=instance_of(PoseMsg))
    map_load_time_ns: int = field(default=0, validator=int_in(0, 2**63 - 1),
                                  metadata=wire("int (ns since the Unix epoch)"))


class OccupancyGrid(SupportedType):
    """A grid map (:class:`~agents_core.messages.OccupancyGridMsg`)."""

    value_class = OccupancyGridMsg

    @classmethod
    def example(cls) -> Any:
        # The origin's header is the grid's own (nav_msgs/OccupancyGrid carries one header).
        header = Header(stamp_ns=1_700_000_000_000_000_011, frame_id="map")
        origin = PoseMsg(position=[-1, -2, 0], header=Header(stamp_ns=header.stamp_ns, frame_id="map"))
        return OccupancyGridMsg(data=np.array([[0, 100], [-1, 50]], np.int8), resolution=0.1, origin=origin,
                                header=header)


class MapMetaData(SupportedType):
    """A grid map's geometry (:class:`~agents_core.messages.MapMetaDataMsg`)."""

    value_class = MapMetaDataMsg

    @classmethod
    def example(cls) -> Any:
        # nav_msgs/MapMetaData has no header: the origin pose has none (stamp 0) either.
        origin = PoseMsg(position=[-5, -2.5, 0], header=unstamped())
        return MapMetaDataMsg(resolution=0.05, width=200, height=100, origin=origin,
                              map_load_time_ns=1_700_000_000_000_000_033)

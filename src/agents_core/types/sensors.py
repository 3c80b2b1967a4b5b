"""Sensor readings: laser scans, point clouds, inertial measurements, satellite fixes and camera calibration.

(A depth camera's aligned frame, RGBD, is an image: it lives in :mod:`agents_core.types.media`.)
"""

from __future__ import annotations

from typing import Any

from attrs import define, field

from ..errors import TypeValidationError
from ..support.lazy_numpy import is_ndarray, np, npt
from .base import SupportedType
from .fields import (
    FLOATS,
    Header,
    Message,
    check_holds,
    empty_f64,
    header_field,
    int_in,
    is_bool,
    is_number,
    is_str,
    named,
    to_array,
    wire,
)

__all__ = [
    "POINT_FIELD_DTYPES",
    "CameraInfo",
    "CameraInfoMsg",
    "Imu",
    "ImuMsg",
    "LaserScan",
    "LaserScanMsg",
    "NavSatFix",
    "NavSatFixMsg",
    "PointCloud2",
    "PointCloud2Msg",
]


def _ranges(value: Any) -> npt.NDArray[np.float32]:
    return to_array(value, np.float32, (None,), "ranges")


def _intensities(value: Any) -> npt.NDArray[np.float32]:
    return to_array(value, np.float32, (None,), "intensities")


@named
@define(eq=False)
class LaserScanMsg(Message):
    """A planar laser scan (angles in radians, ranges in metres)."""

    angle_min: float = field(default=0.0, validator=is_number)
    angle_max: float = field(default=0.0, validator=is_number)
    angle_increment: float = field(default=0.0, validator=is_number)
    time_increment: float = field(default=0.0, validator=is_number)
    scan_time: float = field(default=0.0, validator=is_number)
    range_min: float = field(default=0.0, validator=is_number)
    range_max: float = field(default=0.0, validator=is_number)
    ranges: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                            converter=_ranges, metadata=wire("1-D <f4"))
    intensities: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                                 converter=_intensities, metadata=wire("1-D <f4"))
    header: Header = header_field()


#: The numpy dtypes a point field may have: those of ``sensor_msgs/PointField`` (INT8 .. FLOAT64).
POINT_FIELD_DTYPES = ("i1", "u1", "i2", "u2", "i4", "u4", "f4", "f8")


def _cloud_points(value: Any) -> npt.NDArray[Any]:
    if not is_ndarray(value) or value.dtype.fields is None:
        raise TypeValidationError(
            "field 'points': expected a numpy structured array with float fields x, y, z (e.g. "
            "np.zeros(n, dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4')])), got "
            f"{type(value).__name__}{'' if not is_ndarray(value) else ' of dtype ' + str(value.dtype)}"
        )
    fields = value.dtype.fields
    for axis in ("x", "y", "z"):
        if axis not in fields or fields[axis][0].kind != "f":
            raise TypeValidationError(f"field 'points': needs a float field {axis!r} (has {list(fields)})")
    for name, (dtype, _offset, *_) in fields.items():
        if dtype.shape or f"{dtype.kind}{dtype.itemsize}" not in POINT_FIELD_DTYPES or dtype.byteorder == ">":
            raise TypeValidationError(f"field 'points': point field {name!r} has dtype {dtype}; a point field is "
                                      f"one little-endian {'/'.join(POINT_FIELD_DTYPES)} number")
    if value.ndim == 2 and value.shape[0] == 1:
        value = value[0]  # one row: an unorganised cloud (what ROS calls height 1)
    if value.ndim not in (1, 2):
        raise TypeValidationError(f"field 'points': expected N points or an HxW organised cloud, got shape "
                                  f"{value.shape}")
    points: npt.NDArray[Any] = value
    check_holds(points, "points")
    return points


@named
@define(eq=False)
class PointCloud2Msg(Message):
    """A point cloud: a numpy structured array with float fields ``x``, ``y``, ``z`` and any others
    (``rgb``, ``intensity``, ...), N points or HxW (an organised cloud); ``is_dense`` when no point is invalid."""

    points: npt.NDArray[Any] = field(converter=_cloud_points, metadata=wire(structured=True))
    is_dense: bool = field(default=True, validator=is_bool)
    header: Header = header_field()

    @property
    def xyz(self) -> npt.NDArray[Any]:
        """The coordinates as an Nx3 float array (a copy)."""
        flat = self.points.reshape(-1)
        xyz: npt.NDArray[Any] = np.stack([flat["x"], flat["y"], flat["z"]], axis=-1)
        return xyz


def _covariance_9(value: Any, name: str) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (9,), name)


def _orientation_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "orientation_covariance")


def _angular_velocity_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "angular_velocity_covariance")


def _linear_acceleration_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "linear_acceleration_covariance")


def _position_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "position_covariance")


def _orientation(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (4,), "orientation")


def _angular_velocity(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (3,), "angular_velocity")


def _linear_acceleration(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (3,), "linear_acceleration")


def _zeros_9() -> npt.NDArray[np.float64]:
    return np.zeros(9)


_COVARIANCE = wire("[float x 9] (row-major 3x3)", as_list=True)
_VECTOR3 = wire("[x, y, z] float", as_list=True)


@named
@define(eq=False)
class ImuMsg(Message):
    """An inertial measurement: orientation (quaternion x, y, z, w), angular velocity (rad/s) and linear
    acceleration (m/s²), each with a row-major 3x3 covariance (9 values; element 0 of -1: not estimated)."""

    orientation: npt.NDArray[np.float64] = field(factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]),
                                                 converter=_orientation,
                                                 metadata=wire("[x, y, z, w] float", as_list=True))
    orientation_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_orientation_covariance,
                                                            metadata=_COVARIANCE)
    angular_velocity: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3), converter=_angular_velocity,
                                                      metadata=_VECTOR3)
    angular_velocity_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9,
                                                                 converter=_angular_velocity_covariance,
                                                                 metadata=_COVARIANCE)
    linear_acceleration: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3), converter=_linear_acceleration,
                                                         metadata=_VECTOR3)
    linear_acceleration_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9,
                                                                    converter=_linear_acceleration_covariance,
                                                                    metadata=_COVARIANCE)
    header: Header = header_field()


@named
@define(eq=False)
class NavSatFixMsg(Message):
    """A satellite fix: latitude and longitude (degrees), altitude (m), the fix ``status`` (-1 no fix, 0 fix,
    1 SBAS, 2 GBAS), the ``service`` bits (1 GPS, 2 GLONASS, 4 COMPASS, 8 GALILEO) and an ENU covariance (m²)."""

    latitude: float = field(default=0.0, validator=is_number)
    longitude: float = field(default=0.0, validator=is_number)
    altitude: float = field(default=0.0, validator=is_number)
    status: int = field(default=-1, validator=int_in(-1, 2), metadata=wire("int (-1 no fix, 0 fix, 1 SBAS, 2 GBAS)"))
    service: int = field(default=1, validator=int_in(0, 2**16 - 1), metadata=wire("int (bits: 1 GPS, 2 GLONASS, ...)"))
    position_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_position_covariance,
                                                         metadata=_COVARIANCE)
    position_covariance_type: int = field(default=0, validator=int_in(0, 3),
                                          metadata=wire("int (0 unknown, 1 approximated, 2 diagonal, 3 known)"))
    header: Header = header_field()


def _d(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "d")


def _k(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (9,), "k")


def _r(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (9,), "r")


def _p(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (12,), "p")


def _roi(value: Any) -> npt.NDArray[np.int64]:
    roi = to_array(value, np.int64, (4,), "roi")
    if roi.size and (roi.min() < 0 or roi.max() > 2**32 - 1):
        raise TypeValidationError(f"field 'roi': values must be uint32, got {roi.tolist()}")
    return roi


@named
@define(eq=False)
class CameraInfoMsg(Message):
    """A camera's calibration, as ``sensor_msgs/CameraInfo``: image size, distortion model and
    coefficients ``d``, intrinsics ``k`` (3x3), rectification ``r`` (3x3), projection ``p`` (3x4), all
    row-major; binning; region of interest (x_offset, y_offset, height, width) and whether to rectify it."""

    height: int = field(default=0, validator=int_in(0, 2**32 - 1))
    width: int = field(default=0, validator=int_in(0, 2**32 - 1))
    distortion_model: str = field(default="plumb_bob", validator=is_str,
                                  metadata=wire("str (plumb_bob, rational_polynomial, equidistant, ...)"))
    d: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_d, metadata=FLOATS)
    k: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_k, metadata=wire("[float x 9] (3x3)",
                                                                                      as_list=True))
    r: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_r, metadata=wire("[float x 9] (3x3)",
                                                                                      as_list=True))
    p: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(12), converter=_p,
                                       metadata=wire("[float x 12] (3x4)", as_list=True))
    binning_x: int = field(default=0, validator=int_in(0, 2**32 - 1))
    binning_y: int = field(default=0, validator=int_in(0, 2**32 - 1))
    roi: npt.NDArray[np.int64] = field(factory=lambda: np.zeros(4, np.int64), converter=_roi,
                                       metadata=wire("[x_offset, y_offset, height, width] int", as_list=True))
    roi_do_rectify: bool = field(default=False, validator=is_bool)
    header: Header = header_field()


class LaserScan(SupportedType):
    """A planar scan (:class:`~agents_core.messages.LaserScanMsg`)."""

    value_class = LaserScanMsg

    @classmethod
    def example(cls) -> Any:
        return LaserScanMsg(angle_min=-1.0, angle_max=1.0, angle_increment=0.5, range_max=10.0,
                            ranges=[1, 2, 3, 4, 5], intensities=[])


class PointCloud2(SupportedType):
    """A point cloud (:class:`~agents_core.messages.PointCloud2Msg`); a structured array is wrapped."""

    value_class = PointCloud2Msg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if is_ndarray(value):
            return PointCloud2Msg(points=value)
        return super().validate(value)

    @classmethod
    def example(cls) -> Any:
        # PCL's XYZRGB layout: x, y, z, 4 bytes of padding, rgb packed in a float32; 32 bytes a point.
        dtype = np.dtype({"names": ["x", "y", "z", "rgb"], "formats": ["<f4", "<f4", "<f4", "<u4"],
                          "offsets": [0, 4, 8, 16], "itemsize": 32})
        points = np.zeros(3, dtype)
        points["x"], points["y"], points["z"] = [1.0, 2.0, 3.0], [0.5, -0.5, 0.0], [0.1, 0.2, 0.3]
        points["rgb"] = [0xFF0000, 0x00FF00, 0x0000FF]
        return PointCloud2Msg(points=points, header=Header(stamp_ns=1_700_000_000_000_000_023,
                                                           frame_id="lidar"))


class Imu(SupportedType):
    """An inertial measurement (:class:`~agents_core.messages.ImuMsg`)."""

    value_class = ImuMsg

    @classmethod
    def example(cls) -> Any:
        return ImuMsg(orientation=[0, 0, 0.38268343, 0.92387953], orientation_covariance=[-1] + [0] * 8,
                      angular_velocity=[0.01, -0.02, 0.3], angular_velocity_covariance=np.eye(3).reshape(-1) * 1e-4,
                      linear_acceleration=[0.1, 0.0, 9.81], linear_acceleration_covariance=[np.nan] * 9,
                      header=Header(stamp_ns=1_700_000_000_000_000_025, frame_id="imu_link"))


class NavSatFix(SupportedType):
    """A satellite fix (:class:`~agents_core.messages.NavSatFixMsg`)."""

    value_class = NavSatFixMsg

    @classmethod
    def example(cls) -> Any:
        return NavSatFixMsg(latitude=48.858370, longitude=2.294481, altitude=35.5, status=0, service=1,
                            position_covariance=[4.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0], position_covariance_type=2,
                            header=Header(stamp_ns=1_700_000_000_000_000_027, frame_id="gps"))


class CameraInfo(SupportedType):
    """A camera calibration (:class:`~agents_core.messages.CameraInfoMsg`)."""

    value_class = CameraInfoMsg

    @classmethod
    def example(cls) -> Any:
        k = [525.0, 0, 319.5, 0, 525.0, 239.5, 0, 0, 1]
        return CameraInfoMsg(height=480, width=640, distortion_model="plumb_bob", d=[0.1, -0.2, 0, 0, 0.05],
                             k=k, r=np.eye(3).reshape(-1), p=[525.0, 0, 319.5, 0, 0, 525.0, 239.5, 0, 0, 0, 1, 0],
                             binning_x=1, binning_y=1, roi=[0, 0, 480, 640], roi_do_rectify=False,
                             header=Header(stamp_ns=1_700_000_000_000_000_035, frame_id="camera"))

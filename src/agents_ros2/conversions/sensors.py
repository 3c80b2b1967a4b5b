"""ROS 2 conversions of sensor readings: ``sensor_msgs`` LaserScan, PointCloud2, Imu, NavSatFix and CameraInfo."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from sensor_msgs.msg import CameraInfo as RosCameraInfo
from sensor_msgs.msg import Imu as RosImu
from sensor_msgs.msg import LaserScan as RosLaserScan
from sensor_msgs.msg import NavSatFix as RosNavSatFix
from sensor_msgs.msg import PointCloud2 as RosPointCloud2
from sensor_msgs.msg import PointField as RosPointField

from agents_core import messages as m
from agents_core.errors import TypeValidationError

from .base import NATIVE_BIG_ENDIAN, RosConversion, as_numpy, f32, header_from_ros, header_to_ros, seq

__all__ = ["CONVERSIONS"]


_SCAN_SCALARS = ("angle_min", "angle_max", "angle_increment", "time_increment", "scan_time", "range_min",
                 "range_max")


def _scan_to_ros(v: m.LaserScanMsg) -> RosLaserScan:
    out = RosLaserScan(**{name: getattr(v, name) for name in _SCAN_SCALARS})
    header_to_ros(v.header, out.header)
    out.ranges = seq("f", v.ranges, np.float32)
    out.intensities = seq("f", v.intensities, np.float32)
    return out


def _scan_from_ros(msg: RosLaserScan) -> m.LaserScanMsg:
    scalars = {name: f32(getattr(msg, name)) for name in _SCAN_SCALARS}
    return m.LaserScanMsg(**scalars, ranges=as_numpy(msg.ranges, np.float32),
                          intensities=as_numpy(msg.intensities, np.float32), header=header_from_ros(msg.header))


_POINT_FIELD_TYPES: dict[int, str] = {
    RosPointField.INT8: "i1", RosPointField.UINT8: "u1", RosPointField.INT16: "i2", RosPointField.UINT16: "u2",
    RosPointField.INT32: "i4", RosPointField.UINT32: "u4", RosPointField.FLOAT32: "f4", RosPointField.FLOAT64: "f8",
}
_POINT_FIELD_CODES = {code: datatype for datatype, code in _POINT_FIELD_TYPES.items()}


def _cloud_to_ros(v: m.PointCloud2Msg) -> RosPointCloud2:
    points = v.points
    height, width = (1, points.shape[0]) if points.ndim == 1 else points.shape
    step = points.dtype.itemsize
    out = RosPointCloud2(height=int(height), width=int(width), is_bigendian=NATIVE_BIG_ENDIAN, point_step=step,
                         row_step=step * int(width), is_dense=v.is_dense)
    header_to_ros(v.header, out.header)
    assert points.dtype.fields is not None  # the value class only holds structured arrays
    out.fields = [RosPointField(name=name, offset=offset, datatype=_POINT_FIELD_CODES[f"{dtype.kind}{dtype.itemsize}"],
                                count=1) for name, (dtype, offset, *_) in points.dtype.fields.items()]
    out.data = seq("B", np.ascontiguousarray(points).reshape(-1).view(np.uint8), np.uint8)
    return out


def _cloud_from_ros(msg: RosPointCloud2) -> m.PointCloud2Msg:
    height, width, step, row_step = int(msg.height), int(msg.width), int(msg.point_step), int(msg.row_step)
    order = ">" if msg.is_bigendian else "<"
    names: list[str] = []
    formats: list[str] = []
    offsets: list[int] = []
    for f in msg.fields:
        kind = _POINT_FIELD_TYPES.get(f.datatype)
        if kind is None:
            raise TypeValidationError(f"PointCloud2 field {f.name!r}: datatype {f.datatype} is not a PointField type")
        if f.count != 1:
            raise TypeValidationError(f"PointCloud2 field {f.name!r}: count {f.count} is not supported (only 1)")
        if f.name in names:
            raise TypeValidationError(f"PointCloud2 field {f.name!r} appears twice")
        size = int(kind[1])
        if f.offset + size > step:
            raise TypeValidationError(f"PointCloud2 field {f.name!r}: offset {f.offset} + {size} bytes exceeds "
                                      f"point_step {step}")
        names.append(f.name)
        formats.append(order + kind)
        offsets.append(int(f.offset))
    if row_step < step * width:
        raise TypeValidationError(f"PointCloud2 row_step {row_step} is smaller than width {width} x point_step {step}")
    raw = as_numpy(msg.data, np.uint8)
    if raw.size != row_step * height:
        raise TypeValidationError(f"PointCloud2 data has {raw.size} bytes; {height} rows of row_step {row_step} "
                                  f"need {row_step * height}")
    try:
        dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})
    except (TypeError, ValueError) as exc:
        raise TypeValidationError(f"PointCloud2 fields do not make a point layout: {exc}") from exc
    rows = raw.reshape(height, row_step)[:, :step * width] if height else raw.reshape(0, step * width)
    points = np.ascontiguousarray(rows).view(dtype).reshape(height, width)
    if msg.is_bigendian != NATIVE_BIG_ENDIAN:
        points = points.astype(dtype.newbyteorder())
    return m.PointCloud2Msg(points=points[0] if height == 1 else points, is_dense=bool(msg.is_dense),
                            header=header_from_ros(msg.header))


def _fixed(values: Any) -> npt.NDArray[np.float64]:
    return np.ascontiguousarray(values, dtype=np.float64)


def _imu_to_ros(v: m.ImuMsg) -> RosImu:
    out = RosImu(orientation_covariance=_fixed(v.orientation_covariance),
                 angular_velocity_covariance=_fixed(v.angular_velocity_covariance),
                 linear_acceleration_covariance=_fixed(v.linear_acceleration_covariance))
    header_to_ros(v.header, out.header)
    o = out.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in v.orientation)
    out.angular_velocity.x, out.angular_velocity.y, out.angular_velocity.z = (float(c) for c in v.angular_velocity)
    a = out.linear_acceleration
    a.x, a.y, a.z = (float(c) for c in v.linear_acceleration)
    return out


def _imu_from_ros(msg: RosImu) -> m.ImuMsg:
    o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    return m.ImuMsg(orientation=[o.x, o.y, o.z, o.w], orientation_covariance=_fixed(msg.orientation_covariance),
                    angular_velocity=[w.x, w.y, w.z],
                    angular_velocity_covariance=_fixed(msg.angular_velocity_covariance),
                    linear_acceleration=[a.x, a.y, a.z],
                    linear_acceleration_covariance=_fixed(msg.linear_acceleration_covariance),
                    header=header_from_ros(msg.header))


def _fix_to_ros(v: m.NavSatFixMsg) -> RosNavSatFix:
    out = RosNavSatFix(latitude=float(v.latitude), longitude=float(v.longitude), altitude=float(v.altitude),
                       position_covariance=_fixed(v.position_covariance),
                       position_covariance_type=int(v.position_covariance_type))
    out.status.status, out.status.service = int(v.status), int(v.service)
    header_to_ros(v.header, out.header)
    return out


def _fix_from_ros(msg: RosNavSatFix) -> m.NavSatFixMsg:
    return m.NavSatFixMsg(latitude=msg.latitude, longitude=msg.longitude, altitude=msg.altitude,
                          status=int(msg.status.status), service=int(msg.status.service),
                          position_covariance=_fixed(msg.position_covariance),
                          position_covariance_type=int(msg.position_covariance_type),
                          header=header_from_ros(msg.header))


def _camera_info_to_ros(v: m.CameraInfoMsg) -> RosCameraInfo:
    out = RosCameraInfo(height=int(v.height), width=int(v.width), distortion_model=v.distortion_model,
                        k=_fixed(v.k), r=_fixed(v.r), p=_fixed(v.p), binning_x=int(v.binning_x),
                        binning_y=int(v.binning_y))
    out.d = seq("d", v.d, np.float64)
    roi = out.roi
    roi.x_offset, roi.y_offset, roi.height, roi.width = (int(c) for c in v.roi)
    roi.do_rectify = bool(v.roi_do_rectify)
    header_to_ros(v.header, out.header)
    return out


def _camera_info_from_ros(msg: RosCameraInfo) -> m.CameraInfoMsg:
    roi = msg.roi
    return m.CameraInfoMsg(height=int(msg.height), width=int(msg.width), distortion_model=msg.distortion_model,
                           d=as_numpy(msg.d, np.float64), k=_fixed(msg.k), r=_fixed(msg.r), p=_fixed(msg.p),
                           binning_x=int(msg.binning_x), binning_y=int(msg.binning_y),
                           roi=[roi.x_offset, roi.y_offset, roi.height, roi.width], roi_do_rectify=bool(roi.do_rectify),
                           header=header_from_ros(msg.header))


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "LaserScan": RosConversion(RosLaserScan, _scan_to_ros, _scan_from_ros),
    "PointCloud2": RosConversion(RosPointCloud2, _cloud_to_ros, _cloud_from_ros),
    "Imu": RosConversion(RosImu, _imu_to_ros, _imu_from_ros),
    "NavSatFix": RosConversion(RosNavSatFix, _fix_to_ros, _fix_from_ros),
    "CameraInfo": RosConversion(RosCameraInfo, _camera_info_to_ros, _camera_info_from_ros),
}

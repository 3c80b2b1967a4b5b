"""The ROS 2 adapter for agents_core (install: see docs/ros2.md).

Importing this package does not import ``rclpy``; its modules do:

- :mod:`agents_ros2.transport`: :class:`~agents_ros2.transport.Ros2Transport`, resolved by
  ``Launcher(transport="ros2")``;
- :mod:`agents_ros2.lifecycle`: components as ROS 2 lifecycle nodes;
- :mod:`agents_ros2.conversions`: values <-> ROS messages for every registered type;
- :mod:`agents_ros2.goals`: long-running goals as rclpy action servers and clients;
- :mod:`agents_ros2.qos`: Topic QoS -> ROS QoS, and the Fast DDS shared-memory profile.
"""

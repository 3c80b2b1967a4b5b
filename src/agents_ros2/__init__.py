"""The ROS 2 adapter for agents_core (install with ``pip install 'agents-core[ros2]'``).

Importing this package does not import ``rclpy``; :mod:`agents_ros2.transport` does.
"""

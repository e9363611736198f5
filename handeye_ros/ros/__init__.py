"""The ROS 2 front end (rclpy). Only :mod:`.node` imports rclpy; :mod:`.config` does not."""

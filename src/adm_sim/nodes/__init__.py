"""ROS 2 nodes of adm-sim (the only modules besides launch scripts that import rclpy)."""

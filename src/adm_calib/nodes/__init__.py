"""ROS 2 nodes of adm-calib."""

"""The processes of a node graph: their DDS environment (:mod:`.dds_env`: SHM transport, a locked
``ROS_DOMAIN_ID``, loopback only) and their supervisor (:mod:`.supervisor`: start, watch, stop, and
children that die with their launcher).

No module here imports rclpy; the launch scripts and the tests start nodes through them.
"""

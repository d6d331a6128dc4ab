"""ROS 2 layer of adm-sim: environment set-up, MCAP recording and rerun visualisation.

This subpackage may import rclpy; the numerical core (:mod:`adm_sim.bridge`, :mod:`adm_sim.trains`,
:mod:`adm_sim.stepping`, :mod:`adm_sim.sweep`) never imports it.
"""

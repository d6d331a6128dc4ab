"""Recording and viewing of runs: the MCAP log (:mod:`.mcap_log`), the rerun recording
(:mod:`.rerun_log`), the rerun processes beside it (:mod:`.viewer_process`: analytics opt-out, viewer,
ports) and its views (:mod:`.rerun_blueprint`).

No module here imports rclpy: nodes, launch scripts and ``adm-sim salvage`` use them alike; the names
they write (topics, records, rerun entity paths, run phases) come from :mod:`adm_sim.protocol`.
"""

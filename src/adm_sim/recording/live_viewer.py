"""The rerun output of a live run client: the viewer, the ``.rrd`` file, or both.

:class:`LiveViewer` starts the rerun recording (:func:`adm_sim.recording.rerun_log.init_rerun`,
servers on the loopback only), draws every message it is given through the one topic -> viewer
feed that ``replay.py`` uses (:class:`adm_sim.recording.viewer_feed.ViewerFeed`), closes the
recording, and reads a written ``.rrd`` back (:func:`adm_sim.recording.rrd_check.check_rrd`).
:class:`adm_sim.nodes.recorder.RunRecorder` imports this module only when a run draws: rerun
(~0.9 s) then loads here, so a client that records MCAP alone, or nothing, starts without it.
"""

from __future__ import annotations

from adm_sim.recording import rerun_log
from adm_sim.recording.rrd_check import check_rrd
from adm_sim.recording.viewer_feed import RunPhases, ViewerFeed

__all__ = ["LiveViewer"]


class LiveViewer:
    """A live run's rerun recording and its viewer feed.

    Parameters
    ----------
    save_path : path-like or None
        Where the ``.rrd`` is written (the temporary file beside the final one), or None.
    spawn : bool
        Start a native viewer bound to 127.0.0.1.
    connect_url : str or None
        Stream to a running viewer (a loopback URL).
    """

    def __init__(self, save_path=None, spawn=False, connect_url=None):
        rerun_log.init_rerun("adm_sim", spawn=bool(spawn), connect_url=connect_url or None, save_path=save_path,
                             overwrite=True)
        self.viz = rerun_log.RunLogger()
        self.viz.send_blueprint()  # sent again with the beam bounds once the span is known
        self.feed = ViewerFeed(self.viz, RunPhases("the live run"))

    def __call__(self, topic, msg, t_ns):
        """Draw one message at log time ``t_ns`` (ns)."""
        self.feed(topic, msg, t_ns)

    def close(self):
        """Draw what the feed still holds, then flush and close the recording; a viewer that stopped
        answering is given up with one warning (:func:`adm_sim.recording.rerun_log.close_rerun`)."""
        try:
            self.feed.finish()
        finally:
            rerun_log.close_rerun(watch_viewer=True)

    @staticmethod
    def check_file(path, final):
        """Read the ``.rrd`` written at ``path`` back whole (:class:`adm_sim.errors.RunError` naming
        ``final`` and the ``rrd_path`` parameter when it does not)."""
        return check_rrd(path, final, option="rrd_path")

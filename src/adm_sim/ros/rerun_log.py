"""Visualise adm-sim runs with rerun 0.41: one ``log_*`` function per concern.

Time always comes from the simulation, never from the wall clock: results over time go on the
duration timeline ``sim_time`` (seconds of simulated time, from message stamps), speed sweeps on
the sequence timeline ``speed_kmh`` and calibration steps on the sequence timeline ``iteration``.
Whole arrays go through ``rr.send_columns`` (one call per series, not one per sample).

Entities
--------
``midspan/displacement_m/<lane>``, ``midspan/acceleration_m_s2/<lane>``
    Scalars over ``sim_time`` (:func:`log_midspan`).
``beam/deflection``, ``beam/axles``
    Deflected beam as ``LineStrips2D`` (x along the span in m, y the deflection in m times
    ``exaggeration``) and the axles on the bridge as ``Points2D`` (:func:`log_beam`). Rerun's 2D
    y axis points down, so a positive (downward) deflection shows below the axis.
``sweep/<label>``
    Maximum deck acceleration against train speed, one series per damping trial or model
    (:func:`log_sweep_curve`).
``calibration/delta_zeta_pct``, ``calibration/mlm_peak_m_s2``, ``calibration/dim_peak_m_s2``
    Additional-damping iteration (:func:`log_delta_zeta_iteration`).

Privacy and network
-------------------
Rerun collects usage data by default. It reads its opt-out from its own config file
(``$XDG_CONFIG_HOME/rerun/analytics.json``, written by ``rerun analytics disable``) and skips
analytics whenever the environment variable ``CI`` is set; rerun 0.41 has no other switch (no
``RERUN_ANALYTICS`` variable, no SDK argument). :func:`init_rerun` therefore calls
:func:`ensure_analytics_disabled`, which runs ``rerun analytics disable`` (with ``CI=1`` so that this
command records nothing itself) unless the config already says disabled. A viewer spawned here is
bound to 127.0.0.1 (``rr.spawn`` would bind 0.0.0.0), and ``connect_url`` must be a loopback URL.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlparse

import numpy as np

from adm_sim.errors import InputError

__all__ = [
    "analytics_config_path",
    "close_rerun",
    "ensure_analytics_disabled",
    "init_rerun",
    "log_beam",
    "log_delta_zeta_iteration",
    "log_midspan",
    "log_run_info",
    "log_sweep_curve",
    "rerun_cli",
    "rerun_cli_env",
    "spawn_viewer",
]

SIM_TIME = "sim_time"
_LOOPBACK = {"127.0.0.1", "localhost", "::1"}


# ---------------------------------------------------------------- analytics, CLI


def rerun_cli() -> str:
    """Path of the ``rerun`` executable of this environment (the venv's ``bin/rerun``)."""
    here = Path(sys.executable).with_name("rerun")
    if here.is_file():
        return str(here)
    found = shutil.which("rerun")
    if found is None:
        raise InputError("rerun: no 'rerun' executable next to python or on PATH; "
                         "install rerun-sdk==0.41.0")
    return found


def rerun_cli_env(base: dict | None = None) -> dict:
    """Environment for a ``rerun`` CLI child process: ``CI=1`` (rerun skips analytics on CI)."""
    env = dict(os.environ if base is None else base)
    env.setdefault("CI", "1")
    return env


def analytics_config_path() -> Path:
    """Rerun's analytics config file (``directories::ProjectDirs`` on Linux)."""
    config_home = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(config_home) / "rerun" / "analytics.json"


def _analytics_disabled(path: Path) -> bool:
    try:
        return json.loads(path.read_text()).get("analytics_enabled") is False
    except (OSError, ValueError):
        return False


def ensure_analytics_disabled() -> Path:
    """Make rerun's usage analytics off for this user; return the config file.

    Runs ``rerun analytics disable`` once (idempotent: nothing is run when the config already
    says disabled). Raises :class:`InputError` if the config cannot be written.
    """
    path = analytics_config_path()
    if _analytics_disabled(path):
        return path
    subprocess.run([rerun_cli(), "analytics", "disable"], env=rerun_cli_env(),
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=60, check=False)
    if not _analytics_disabled(path):
        raise InputError(
            f"rerun analytics: could not disable usage analytics (config '{path}'); "
            "run 'rerun analytics disable' by hand"
        )
    return path


# ---------------------------------------------------------------- set-up


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for_port(port: int, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return True
        except OSError:
            time.sleep(0.1)
    return False


def spawn_viewer(port: int | None = None, memory_limit: str = "25%",
                 timeout_s: float = 20.0) -> tuple[subprocess.Popen, str]:
    """Start a native rerun viewer bound to 127.0.0.1; return the process and its proxy URL.

    ``rr.spawn`` cannot choose the bind address (the viewer would listen on 0.0.0.0), hence this.
    """
    port = _free_port() if port is None else int(port)
    proc = subprocess.Popen(
        [rerun_cli(), "--bind", "127.0.0.1", "--port", str(port),
         "--memory-limit", memory_limit],
        env=rerun_cli_env({k: v for k, v in os.environ.items()} | {"RERUN_APP_ONLY": "true"}),
        stdin=subprocess.DEVNULL, start_new_session=True,
    )
    if not _wait_for_port(port, timeout_s):
        proc.kill()
        proc.wait()
        raise InputError(f"spawn: the rerun viewer did not listen on 127.0.0.1:{port} "
                         f"within {timeout_s:g} s (is there a display?)")
    return proc, f"rerun+http://127.0.0.1:{port}/proxy"


def _check_loopback(url: str) -> str:
    host = urlparse(url).hostname
    if urlparse(url).scheme not in ("rerun", "rerun+http", "rerun+https") or host is None:
        raise InputError(f"connect_url: {url!r} is not a rerun URL "
                         "(e.g. rerun+http://127.0.0.1:9876/proxy)")
    if host not in _LOOPBACK and not host.startswith("127."):
        raise InputError(f"connect_url: host {host!r} is not on this machine; "
                         "allowed 127.0.0.0/8, localhost, ::1")
    return url


def init_rerun(app_id: str, spawn: bool = False, connect_url: str | None = None,
               save_path=None, overwrite: bool = False, recording_id: str | None = None):
    """Start a rerun recording with analytics off and servers on the loopback only.

    Parameters
    ----------
    app_id : str
        Application id, e.g. ``"adm_sim"``.
    spawn : bool
        Start a native viewer bound to 127.0.0.1 and stream to it.
    connect_url : str or None
        Stream to a running viewer, e.g. ``"rerun+http://127.0.0.1:9876/proxy"`` (loopback only).
    save_path : path-like or None
        Also (or only) write an ``.rrd`` file; an existing one is refused unless ``overwrite``.
    recording_id : str or None
        Fixed recording id (several processes logging into one recording).

    Returns
    -------
    rerun.RecordingStream
        The global recording; the ``log_*`` functions log to it unless given ``recording=``.
        A spawned viewer is detached (its own session) and outlives this process.

    With no sink at all the data are buffered in memory (``rr.init`` default behaviour).
    """
    import rerun as rr

    ensure_analytics_disabled()
    sinks = []
    viewer = None
    if spawn and connect_url is not None:
        raise InputError("init_rerun: give spawn=True or connect_url, not both")
    if spawn:
        viewer, connect_url = spawn_viewer()
    if connect_url is not None:
        sinks.append(rr.GrpcSink(_check_loopback(connect_url)))
    if save_path is not None:
        save_path = Path(save_path)
        if save_path.exists() and not overwrite:
            raise InputError(f"save_path: '{save_path}' already exists; refusing to overwrite it "
                             "(pass overwrite=True or choose another file)")
        if save_path.suffix != ".rrd":
            raise InputError(f"save_path: '{save_path}' must end in .rrd")
        sinks.append(rr.FileSink(str(save_path)))
    rr.init(app_id, recording_id=recording_id, spawn=False)
    if sinks:
        rr.set_sinks(*sinks)
    rec = rr.get_global_data_recording()
    if viewer is not None:
        _VIEWERS.append(viewer)
    return rec


_VIEWERS: list[subprocess.Popen] = []


def close_rerun(recording=None) -> None:
    """Flush and close the sinks of the recording (the ``.rrd`` file is complete afterwards)."""
    import rerun as rr

    rr.disconnect(recording=recording)


def _part(label) -> str:
    import rerun as rr

    return rr.escape_entity_path_part(str(label))


def _times(t_s) -> np.ndarray:
    return np.atleast_1d(np.asarray(t_s, dtype=np.float64))


# ---------------------------------------------------------------- log_* functions


def log_midspan(t_s, disp_m, acc_m_s2, lane_label, recording=None) -> None:
    """Mid-span displacement and acceleration of one speed lane over simulated time.

    Parameters
    ----------
    t_s : float or array (n,)
        Simulated time in s.
    disp_m, acc_m_s2 : float or array (n,) or None
        Mid-span displacement in m (positive downward) and vertical acceleration in m/s^2;
        ``None`` logs the other one only.
    lane_label : str
        Lane name, e.g. ``"300 km/h"``; escaped into one entity-path part.
    """
    import rerun as rr

    lane = _part(lane_label)
    t = _times(t_s)
    series = {}
    for name, values in (("displacement_m", disp_m), ("acceleration_m_s2", acc_m_s2)):
        if values is None:
            continue
        v = np.atleast_1d(np.asarray(values, dtype=np.float64))
        if v.shape != t.shape or t.ndim != 1:
            raise InputError(f"log_midspan: t_s {t.shape} and {name} {v.shape} must be scalars "
                             "or arrays of one equal length")
        series[f"midspan/{name}/{lane}"] = v
    if np.ndim(t_s) == 0:
        rr.set_time(SIM_TIME, duration=float(t[0]), recording=recording)
        for path, v in series.items():
            rr.log(path, rr.Scalars(v[0]), recording=recording)
        return
    index = [rr.TimeColumn(SIM_TIME, duration=t)]
    for path, v in series.items():
        rr.send_columns(path, indexes=index, columns=rr.Scalars.columns(scalars=v),
                        recording=recording)


def log_beam(t_s, x_m, w_m, axle_x_m, axle_w_m, exaggeration: float = 1.0,
             recording=None) -> None:
    """Deflected beam and the axles on it at one simulated time.

    Parameters
    ----------
    t_s : float
        Simulated time in s.
    x_m, w_m : array (n,)
        Positions along the span in m and deflection there in m (positive downward).
    axle_x_m : array (n_on,)
        Positions of the axles on the bridge in m (``n_on`` may be 0).
    axle_w_m : float or array (n_on,)
        Deflection under each axle in m.
    exaggeration : float
        Factor on the deflections for display (a few mm on a 20 m span are invisible at 1).
    """
    import rerun as rr

    x = np.asarray(x_m, dtype=np.float64).ravel()
    w = np.asarray(w_m, dtype=np.float64).ravel()
    if x.shape != w.shape:
        raise InputError(f"log_beam: x_m {x.shape} and w_m {w.shape} must have equal length")
    ax = np.asarray(axle_x_m, dtype=np.float64).ravel()
    aw = np.broadcast_to(np.asarray(axle_w_m, dtype=np.float64), ax.shape) if ax.size else ax
    k = float(exaggeration)
    rr.set_time(SIM_TIME, duration=float(t_s), recording=recording)
    rr.log("beam/deflection", rr.LineStrips2D([np.column_stack([x, k * w])]),
           recording=recording)
    rr.log("beam/axles", rr.Points2D(np.column_stack([ax, k * aw]).reshape(-1, 2), radii=0.15),
           recording=recording)


def log_sweep_curve(label, speeds_kmh, max_acc_m_s2, recording=None) -> None:
    """Maximum deck acceleration against train speed for one damping trial or model.

    Parameters
    ----------
    label : str
        Series name, e.g. ``"MLM zeta=1.0%"`` or ``"DIM"``.
    speeds_kmh : array (n_speeds,)
        Train speeds in km/h; the ``speed_kmh`` sequence timeline holds them rounded to 1 km/h.
    max_acc_m_s2 : array (n_speeds,)
        Maximum vertical deck acceleration in m/s^2 at each speed.
    """
    import rerun as rr

    v = np.atleast_1d(np.asarray(speeds_kmh, dtype=np.float64))
    a = np.atleast_1d(np.asarray(max_acc_m_s2, dtype=np.float64))
    if v.shape != a.shape or v.ndim != 1:
        raise InputError(f"log_sweep_curve: speeds_kmh {v.shape} and max_acc_m_s2 {a.shape} "
                         "must have equal length")
    if not np.all(np.isfinite(v)) or np.any(v < 0):
        raise InputError("log_sweep_curve: speeds_kmh must be finite and >= 0 km/h")
    rr.send_columns(f"sweep/{_part(label)}",
                    indexes=[rr.TimeColumn("speed_kmh", sequence=np.rint(v).astype(np.int64))],
                    columns=rr.Scalars.columns(scalars=a), recording=recording)


def log_delta_zeta_iteration(i, delta_zeta_pct, mlm_peak, dim_peak, recording=None) -> None:
    """One step of the additional-damping calibration (Delta zeta, in percent).

    Parameters
    ----------
    i : int
        Iteration number (``iteration`` sequence timeline).
    delta_zeta_pct : float
        Trial additional damping in % of critical.
    mlm_peak, dim_peak : float
        Peak deck accelerations in m/s^2 of the MLM with ``delta_zeta_pct`` and of the DIM.
    """
    import rerun as rr

    rr.set_time("iteration", sequence=int(i), recording=recording)
    rr.log("calibration/delta_zeta_pct", rr.Scalars(float(delta_zeta_pct)), recording=recording)
    rr.log("calibration/mlm_peak_m_s2", rr.Scalars(float(mlm_peak)), recording=recording)
    rr.log("calibration/dim_peak_m_s2", rr.Scalars(float(dim_peak)), recording=recording)


def log_run_info(info: dict, recording=None) -> None:
    """Run information (bridge, train, model, speeds) as a static markdown table at ``run``."""
    import rerun as rr

    rows = "\n".join(f"| {k} | {v} |" for k, v in info.items())
    rr.log("run", rr.TextDocument(f"| key | value |\n|---|---|\n{rows}\n",
                                  media_type=rr.MediaType.MARKDOWN),
           static=True, recording=recording)

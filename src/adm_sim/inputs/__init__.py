"""Readers of user input that stand at the edge of the project: bridges (names, ``key=value`` specs,
TOML files), trains (names, both train-file forms), speeds, job files, measured data, a data
logger's CSV. Each turns what was typed into numbers and arrays (or one
:class:`adm_sim.errors.InputError` line); the model behind them knows no files and no spellings."""

from adm_sim import lazy_getattr

#: the public names of the wing and the module that holds each (:func:`adm_sim.lazy_getattr`)
_HOME = {"resolve_bridge": "bridges", "bridge_from_mapping": "bridges", "load_train": "train_files",
         "train_from_mapping": "train_files", "parse_speeds": "speeds"}
__all__ = sorted(_HOME)

__getattr__ = lazy_getattr(__name__, _HOME)

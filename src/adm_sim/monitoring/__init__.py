"""Monitoring: passages of trains in a measured acceleration record and the first mode identified from them."""

import importlib

#: the public names of the wing and the module that holds each (imported on first use, PEP 562, so
#: importing the wing stays as cheap as before; docs/python.md lists them)
_HOME = {"IdentifySettings": "modal_id", "ModalFit": "modal_id", "Passage": "modal_id", "PassageTracker": "modal_id",
         "acc_level": "modal_id", "analyse_passage": "modal_id", "analyse_record": "modal_id",
         "identify_first_mode": "modal_id", "run_topics_for": "modal_id", "segment_signal": "modal_id",
         "uniform_samples": "modal_id"}
__all__ = sorted(_HOME)


def __getattr__(name):
    if name in _HOME:
        return getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

"""Monitoring: passages of trains in a measured acceleration record and the first mode identified from them."""

from adm_sim import lazy_getattr

#: the public names of the wing and the module that holds each (:func:`adm_sim.lazy_getattr`)
_HOME = {"IdentifySettings": "modal_records", "ModalFit": "modal_records", "Passage": "modal_records",
         "PassageTracker": "modal_tracker", "acc_level": "modal_records", "analyse_passage": "modal_passages",
         "analyse_record": "modal_passages", "identify_first_mode": "modal_fit", "run_topics_for": "modal_tracker",
         "segment_signal": "modal_passages", "uniform_samples": "modal_fit"}
__all__ = sorted(_HOME)

__getattr__ = lazy_getattr(__name__, _HOME)

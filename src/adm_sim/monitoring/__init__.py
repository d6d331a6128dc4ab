"""Monitoring: passages of trains in a measured acceleration record and the first mode identified from them."""

from adm_sim import lazy_getattr

#: the public names of the wing and the module that holds each (:func:`adm_sim.lazy_getattr`)
_HOME = {"IdentifySettings": "modal_id", "ModalFit": "modal_id", "Passage": "modal_id", "PassageTracker": "modal_id",
         "acc_level": "modal_id", "analyse_passage": "modal_id", "analyse_record": "modal_id",
         "identify_first_mode": "modal_id", "run_topics_for": "modal_id", "segment_signal": "modal_id",
         "uniform_samples": "modal_id"}
__all__ = sorted(_HOME)

__getattr__ = lazy_getattr(__name__, _HOME)

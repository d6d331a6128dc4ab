"""The parametric study of paper Section 3.3 and the lower-bound fit of Section 4.2.1.

Study
    Every (bridge, train) case of the 1110-bridge field (:func:`adm_sim.model.bridge.parametric_field`,
    185 (L, n0) pairs x 6 mass functions, Table 2 damping) times the four trains is calibrated by
    the rules of :func:`adm_calib.calibrate.calibrate` (Section 4, steps 1-3), in batches of the
    six mass functions of one (L, n0) pair (:func:`adm_calib.calibrate.calibrate_batch`). Batches run
    as tasks on a ``dask.distributed`` cluster: a loopback-only :class:`~distributed.LocalCluster` by default, or
    an existing scheduler. The client process appends one JSON object per finished case to
    ``results.jsonl`` (write, flush, ``os.fsync``), so a crash loses at most the cases still
    running; a rerun skips the cases already in the file (key: bridge name and train). Each line
    carries the CRC-32 of its JSON: readers refuse a damaged line naming its line number and byte
    offset; a rerun drops damaged lines and a truncated last line, one line each, and computes those
    cases again. A scheduler without a worker for 30 s stops the study (exit 1, resumable). A case
    that raises is recorded with ``status: "error"``.

Lower-bound fit (Section 4.2.1, Eq. 20)
    Per train and mass function, the n0 axis is cut into intervals (0.5 Hz from 2 to 8 Hz, then
    boundaries at 9, 10, 11, 13, 16 and 21 Hz); the smallest Δζ_VBI of each interval, at the n0 of
    the case that has it, is a data point; a cubic ``dz = a n0^3 + b n0^2 + c n0 + d`` is fitted to
    the data points by linear least squares (:func:`numpy.polyfit`), with R² and the residuals
    ``data - fit`` about the data points. The function holds from 2.1 Hz to its first real root
    above 2.1 Hz (the "upper limit"), and is 0 beyond. Cases above 21 Hz are not used (paper:
    too few results there). Cases without Δζ_VBI (no reasonable peak, no match, errors) are left
    out and counted; optionally also the cases the paper settled by eye (largest MLM value at an
    end of the speed range, associated DIM value not a local maximum).

Modules: :mod:`~adm_calib.study.cases` (case selection, settings), :mod:`~adm_calib.study.store`
(the result store), :mod:`~adm_calib.study.execution` (batches on dask),
:mod:`~adm_calib.study.fit` (lower-bound fit, Table B range check), :mod:`~adm_calib.study.conservative`
(the conservative lower bound, linear programmes), :mod:`~adm_calib.study.recheck` (the range-end
flag re-derived from fresh MLM curves); Eq. (20) itself is :mod:`adm_calib.lower_bound`; the
figures are in :mod:`adm_calib.plots`.
Imports: numpy and scipy; dask only inside :func:`run_study`, matplotlib only in the plots.
"""

from adm_calib.study.cases import (FREQ_INDICES, INTERVAL_EDGES_HZ, LOWER_LIMIT_HZ, MASS_FUNCTION_NAMES,
                                   SPAN_RANGE_M, STUDY_TRAINS, TRAIN_VARIANTS, WORKER_ENV, StudyCase, StudySettings,
                                   canonical_trains, case_identity, paper_train, select_cases)
from adm_calib.study.execution import (StudyRun, local_cluster, make_batches, run_batch, run_case,
                                       run_study)
from adm_calib.study.fit import (COMPARE_N0_HZ, DEFAULT_RULE, EXCLUSION_RULES, EXCLUSIONS, CubicFit, IntervalMinimum, LowerBoundFit, StudyFit, fit_cubic,
                                 case_flags, comparison_markdown, fit_edges_hz, fit_study,
                                 interval_minima)
from adm_calib.study.store import (LOCK_NAME, META_FORMAT, META_NAME, OLD_FORMATS, RESULTS_NAME, ResultsContent,
                                   ResultsWriter, error_record, read_meta, read_results, record_key,
                                   result_record, versions)

__all__ = [
    "FREQ_INDICES", "INTERVAL_EDGES_HZ", "LOWER_LIMIT_HZ", "MASS_FUNCTION_NAMES", "SPAN_RANGE_M", "STUDY_TRAINS",
    "TRAIN_VARIANTS", "paper_train", "fit_edges_hz", "WORKER_ENV", "StudyCase", "StudySettings", "canonical_trains", "case_identity", "select_cases",
    "StudyRun", "local_cluster", "make_batches", "run_batch", "run_case", "run_study",
    "COMPARE_N0_HZ", "DEFAULT_RULE", "EXCLUSION_RULES", "case_flags", "comparison_markdown",
    "EXCLUSIONS", "CubicFit", "IntervalMinimum", "LowerBoundFit", "StudyFit", "fit_cubic", "fit_study",
    "interval_minima", "LOCK_NAME", "META_FORMAT", "META_NAME", "OLD_FORMATS", "RESULTS_NAME", "ResultsContent",
    "ResultsWriter", "error_record", "read_meta", "read_results", "record_key", "result_record", "versions",
]

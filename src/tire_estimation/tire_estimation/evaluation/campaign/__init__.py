"""Evaluation campaigns on simulated drives: calibration accuracy and ECE R-64 detection.

Two studies (Lundquist et al., IEEE T-ITS 2014, Section IV):

* :func:`run_calibration_study` -- ``ece_r64`` drives without deflation; MPF and AUG-KF side by
  side (one :class:`RadiusEstimator` with ``run_aug_kf=True``); errors against the simulator's
  true radii at a fixed time (10 min), at the end, time to converge within 0.5 mm, and the
  consistency of the reported std (NEES, fraction within 2 std).
* :func:`run_ece_r64_campaign` -- one-wheel 20 % step deflations, robustness drives without
  deflation and slow diffusion on up to four wheels; the MPF and the AUG-KF estimates of the
  *same* run each feed a fresh CUSUM detector (:func:`run_detector_over_trace`). Detection rate,
  detection times, false alarms (count and rate per monitored hour), estimated radius change.

Every case is a picklable :class:`CaseSpec`; :func:`run_case` turns one into a flat result row
(JSON-ready). Cases run on Dask (``dask.distributed``; a LocalCluster by default, or a remote
scheduler), on a process pool, or serially (:func:`execute_cases`). All randomness comes from the
case seed: the simulator's seed and the particle filter's generator (``seed + 1_000_003``).

Modules: ``spec`` (case lists), ``trace`` (one case's traces and their files), ``run`` (one
case end to end), ``score`` (detection and accuracy of one case), ``execute`` (Dask, process
pool, serial), ``summary`` (aggregation), ``output`` (CSV, plots), ``study`` (result
directories), ``cli`` (the ``campaign`` sub-command; ``python -m
tire_estimation.evaluation.campaign``).
"""

from tire_estimation.evaluation.campaign.cli import add_campaign_parser, main
from tire_estimation.evaluation.campaign.execute import Execution, execute_cases, local_cluster
from tire_estimation.evaluation.campaign.output import read_csv_rows, write_csv
from tire_estimation.evaluation.campaign.run import redetect_case, run_case
from tire_estimation.evaluation.campaign.score import braking_signal
from tire_estimation.evaluation.campaign.spec import (
    DIFFUSION_DEADLINE_S,
    GNSS_LEVELS,
    PF_SEED_OFFSET,
    ROAD_LEVELS,
    STEP_DEADLINE_S,
    TARGET_ABSOLUTE_M,
    TARGET_RELATIVE_M,
    TYRE_SENSITIVITIES_MM_PER_KPA,
    CampaignError,
    CaseSpec,
    EceCampaignPlan,
    calibration_cases,
    ece_r64_cases,
)
from tire_estimation.evaluation.campaign.study import (
    merge_ece_r64_campaigns,
    redetect_campaigns,
    run_calibration_study,
    run_ece_r64_campaign,
)
from tire_estimation.evaluation.campaign.summary import (
    split_alarms,
    summarize_calibration,
    summarize_detection,
)
from tire_estimation.evaluation.campaign.trace import CaseRun, load_run, save_run

__all__ = [
    "DIFFUSION_DEADLINE_S",
    "GNSS_LEVELS",
    "PF_SEED_OFFSET",
    "ROAD_LEVELS",
    "STEP_DEADLINE_S",
    "TARGET_ABSOLUTE_M",
    "TARGET_RELATIVE_M",
    "TYRE_SENSITIVITIES_MM_PER_KPA",
    "CampaignError",
    "CaseRun",
    "CaseSpec",
    "EceCampaignPlan",
    "Execution",
    "add_campaign_parser",
    "braking_signal",
    "calibration_cases",
    "ece_r64_cases",
    "execute_cases",
    "load_run",
    "local_cluster",
    "main",
    "merge_ece_r64_campaigns",
    "read_csv_rows",
    "redetect_campaigns",
    "redetect_case",
    "run_calibration_study",
    "run_case",
    "run_ece_r64_campaign",
    "save_run",
    "split_alarms",
    "summarize_calibration",
    "summarize_detection",
    "write_csv",
]

"""Experiments above the planner: validation trials (plan + MuJoCo rollout), campaigns (the paper's Table I), their
statistics, reports and figures.
"""

from softsig_service.experiments.campaign import (
    CampaignResult,
    default_workers,
    read_records,
    run_campaign,
    run_trial_spec,
)
from softsig_service.experiments.campaign_spec import CampaignSpec, TrialSpec, trial_seed
from softsig_service.experiments.capture import CaptureGrid, build_capture_model, simulate_relative_yaw
from softsig_service.experiments.closure_plot import magnitude_label, plot_closure_signature
from softsig_service.experiments.report import plot_summary, records_csv, report_markdown, write_report
from softsig_service.experiments.statistics import fisher_p, summarize, wilson_interval
from softsig_service.experiments.stiffness_plot import plot_stiffness_signature
from softsig_service.experiments.trial import TrialResult, default_planner, run_trial, shift_plan

__all__ = [
    "CampaignResult",
    "CampaignSpec",
    "CaptureGrid",
    "TrialResult",
    "TrialSpec",
    "build_capture_model",
    "default_planner",
    "default_workers",
    "fisher_p",
    "magnitude_label",
    "plot_closure_signature",
    "plot_stiffness_signature",
    "plot_summary",
    "read_records",
    "records_csv",
    "report_markdown",
    "run_campaign",
    "run_trial",
    "run_trial_spec",
    "shift_plan",
    "simulate_relative_yaw",
    "summarize",
    "trial_seed",
    "wilson_interval",
    "write_report",
]

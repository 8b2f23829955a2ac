"""The study: where does opening the hand pay? Paired trials of scene families, error
sources and policies, executed in physics (``openup-ompl study``)."""

from openup_ompl.study.run import StudyOptions
from openup_ompl.study.sweep import StudyResult, run_study

__all__ = ["StudyOptions", "StudyResult", "run_study"]

"""Planners written for this project (OMPL's own planners are used as they are)."""

from openup_ompl.planners.ikbirrt import IKBiRRT, IKBiRRTOptions

__all__ = ["IKBiRRT", "IKBiRRTOptions"]

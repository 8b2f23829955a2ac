"""Perception of the object to grasp: a simulated depth camera (MuJoCo ray casting, the
Kinect noise model of Nguyen et al. 2012), a Solina-Bajcsy superquadric fit with the
covariance of its pose, and the rule that turns that covariance into the hand law's ``u``.
"""

from openup_ompl.perception.camera import CameraOptions, DepthCamera, DepthView
from openup_ompl.perception.covariance import SuperquadricFit
from openup_ompl.perception.fit import FitOptions, Silhouette, fit_superquadric
from openup_ompl.perception.fusion import Fused, fuse
from openup_ompl.perception.noise import NoiseOptions, PointCloud, kinect_sigmas, noisy_cloud
from openup_ompl.perception.perceive import (
    Perception,
    at_estimate,
    estimated_pose,
    perceive,
    perceived_toml,
    write_perception,
)
from openup_ompl.perception.superquadric import Superquadric
from openup_ompl.perception.uncertainty import (
    COVERAGE,
    arrival_fraction,
    clearance_per_u,
    lateral_sigma,
    u_from_covariance,
)

__all__ = [
    "COVERAGE",
    "CameraOptions",
    "DepthCamera",
    "DepthView",
    "FitOptions",
    "Fused",
    "NoiseOptions",
    "Perception",
    "PointCloud",
    "Silhouette",
    "Superquadric",
    "SuperquadricFit",
    "arrival_fraction",
    "at_estimate",
    "clearance_per_u",
    "estimated_pose",
    "fit_superquadric",
    "fuse",
    "kinect_sigmas",
    "lateral_sigma",
    "noisy_cloud",
    "perceive",
    "perceived_toml",
    "u_from_covariance",
    "write_perception",
]

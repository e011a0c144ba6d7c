"""Density estimation and mean-field feedback (paper, "Density tracking control").

* :mod:`control.kde` -- reflected Gaussian kernel density estimate p_hat of the robots
  (eq. "KDE", with the Neumann image kernel so that no mass leaks through the walls) and its
  gradient, by linear binning and DCT smoothing.
* :mod:`control.feedback` -- the velocity of eq. "density feedback law using estimation",
  with a density floor and speed saturation (see that module for what they do to the
  stability results).
* :mod:`control.stirring`, :mod:`control.poisson_flux` -- a divergence-free stirring flux and a global
  transport flux added to the law's numerator (beyond the paper).
* :mod:`control.spreading` -- best-candidate landing points: each robot's next measurement moved within a
  small radius into the largest hole of the measurements so far (blue noise inside the planned density).

* :mod:`control.flooded` -- distributed density estimation by flooded positions: every robot's own p̂
  and ∇p̂ as the centre's KDE of the positions that reached it within a hop bound per sub-step (the
  decentralized swarm's default).
* :mod:`control.consensus` -- distributed density estimation: every robot's own p̂ and ∇p̂ from its
  neighbours' messages (PI dynamic average consensus on the cosine moments of the positions), for a
  swarm without a communication centre.

* :mod:`control.robot_kernel` -- the per-robot work of a feedback sub-step (KDE binning, p_hat, p_r,
  v_r, the law, the Euler--Maruyama step) in compiled C loops for large swarms, with the NumPy code
  as the reference and the fallback.

NumPy/SciPy (and the system C compiler when present); the reference (p_r, v_r) comes from
:class:`ocp.plan.ReferencePlan`.
"""
from .feedback import SPREAD_PRIORITIES, FeedbackSettings, add_within_speed, feedback_velocity, saturate, tracking_velocity
from .kde import DensityEstimate, KernelDensity, silverman_bandwidth
from . import robot_kernel

__all__ = ["KernelDensity", "DensityEstimate", "silverman_bandwidth",
           "FeedbackSettings", "feedback_velocity", "tracking_velocity", "saturate", "add_within_speed",
           "SPREAD_PRIORITIES"]

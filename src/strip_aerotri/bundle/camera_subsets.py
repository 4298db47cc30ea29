"""A subset of the camera parameters from one adjustment with more of them.

An adjustment that estimates a set of camera parameters ends with their
border's Schur complement ``C`` (k x k, the information left to them once the
photos and points are estimated too; ``C = Q⁻¹`` with ``Q`` their cofactor
block), their estimates ``θ`` (increments from the start camera) and the
weighted sum of squares ``Ω``.  Linearised at that solution, the sum of
squares of any other value ``θ'`` of the camera, with photos and points
adjusted to it, is

    Ω(θ') = Ω + (θ' - θ)ᵀ C (θ' - θ).

Holding the parameters ``H`` at their start values (``θ'_H = 0``) and
estimating the rest ``S`` therefore gives, exactly for the linearised problem,

    θ_S = C_SS⁻¹ b_S  with  b = C θ,      Q_S = C_SS⁻¹,
    Ω_S = Ω + θᵀ C θ - b_Sᵀ C_SS⁻¹ b_S,   r_S = r + |H|,

and the adjustment without a camera ``Ω_∅ = Ω + θᵀ C θ``, ``r_∅ = r + k``.
The information of each parameter (``G_ii``, its own normal block) and its
conditional information ``C_ii`` do not depend on which other camera
parameters are estimated, so neither does its multiple correlation with the
orientation and the points.  The choice of ``"auto"``
(:mod:`strip_aerotri.bundle.selfcal`) walks its subsets with this algebra,
k x k, instead of adjusting the block again for each one; the set it ends
with is adjusted for real and checked again.  The linearisation leaves out
the nonlinearity of the camera's change: on a simulated drone strip with
25 µm of camera errors (tests/test_camera_subsets.py), holding two
significant parameters (t -5.6, -6.1) is predicted within 0.34 of the 70 by
which it raises the sum of squares, and every subset's t values within
0.011 and its estimates within 0.015 standard deviations of its own
adjustment.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray
from ..geometry.camera_model import CameraModel
from ..results import BundleResult, CameraEstimate

__all__ = ["LinearisedCamera"]


@dataclass(frozen=True)
class LinearisedCamera:
    """One adjustment's camera, linearised at its solution (module notes).

    Attributes
    ----------
    estimate : CameraEstimate
        The parameters estimated (values, cofactors, sigma0 and the
        information behind their multiple correlations).
    cost : float
        The weighted sum of squares ``Ω`` (``sigma0² r``).
    redundancy : int
        Its redundancy ``r``.
    """

    estimate: CameraEstimate
    cost: float
    redundancy: int

    @classmethod
    def of(cls, result: BundleResult) -> LinearisedCamera:
        """The camera of an adjustment that estimated one."""
        if result.camera is None:
            raise ValueError("Expected an adjustment that estimated a camera")
        return cls(
            result.camera, float(result.camera.sigma0**2 * result.redundancy), result.redundancy
        )

    @property
    def schur(self) -> FloatArray:
        """``C = Q⁻¹`` (k x k), the border's Schur complement."""
        c = np.asarray(np.linalg.inv(self.estimate.cofactor), dtype=np.float64)
        out: FloatArray = 0.5 * (c + c.T)
        return out

    @property
    def cost_without(self) -> float:
        """``Ω_∅ = Ω + θᵀ C θ``: the sum of squares with the camera as given."""
        theta = self.estimate.values
        return float(self.cost + theta @ self.schur @ theta)

    def subset(self, names: Sequence[str], model: CameraModel) -> LinearisedCamera:
        """The estimate of ``names`` (a subset of the estimated parameters) with
        the others held at their start values; ``model`` estimates ``names``."""
        est = self.estimate
        if tuple(model.estimated) != tuple(n for n in est.names if n in set(names)):
            raise ValueError(
                f"Expected a model estimating {tuple(names)} in the order of {est.names}, "
                f"got {model.estimated}"
            )
        keep = np.array([n in set(names) for n in est.names])
        c = self.schur
        theta = est.values
        b = c @ theta
        c_ss = c[np.ix_(keep, keep)]
        q_s = np.linalg.inv(c_ss) if keep.any() else np.zeros((0, 0))
        q_s = 0.5 * (q_s + q_s.T)
        theta_s = q_s @ b[keep]
        cost = float(self.cost + theta @ b - b[keep] @ theta_s)
        redundancy = self.redundancy + int(np.count_nonzero(~keep))
        sigma0 = float(np.sqrt(cost / redundancy)) if redundancy > 0 else float("nan")
        sub = CameraEstimate(
            model=model,
            values=theta_s,
            cofactor=q_s,
            sigma0=sigma0,
            information=est.information[keep],
            conditional_information=est.conditional_information[keep],
        )
        return dataclasses.replace(self, estimate=sub, cost=cost, redundancy=redundancy)

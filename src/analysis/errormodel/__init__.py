"""Error models for control software, fitted to a result dataset, loadable without simgap.

Pose error and detection probability of each tag as smooth functions of distance and obliquity.

Covariates (the same geometry as :meth:`simgap.core.rig.Rig.view_angle`, from a tag pose in the
global frame):

``distance`` (m)
    Distance from the eyepoint to the tag centre, ``|t|``.
``obliquity`` (rad)
    Angle between the tag normal and the line of sight to the camera, signed by which way the tag
    is turned about global +Z (positive: the normal turned counter-clockwise from the line of
    sight, as tag 0 for theta in (0, pi/2)). ``|obliquity| = pi/2 - view_angle``; 0 is a tag
    facing the camera squarely. The sign matters: lateral and yaw errors change sign with it.

Method (per tag and error axis, on the detected configurations of one variant, every repeat):

1. **Bias**: robust local-linear regression (LOESS) of the signed error on (distance,
   obliquity), Gaussian kernel with bandwidths ``h_distance``, ``h_obliquity``; three bisquare
   robustness iterations (Cleveland 1979), so single bad detections do not move it.
2. **Spread**: a kernel-weighted median of the absolute leave-one-out residuals times
   :data:`simgap.core.robust.MAD_TO_SIGMA`
   (a local MAD, the standard deviation for Gaussian errors), so the spread grows where the
   errors do. Its Gaussian-equivalent scale is then calibrated: the training set's leave-one-out
   residuals, divided by the predictive standard deviation, must have their 90 % central interval
   at +-1.645 (one factor per tag and axis, stored as ``calibration``).
3. **Bias uncertainty** (``bias_se``): the standard error of the local fit, ``spread *
   sqrt(sum l_i**2)`` with ``l`` the smoother's weights at the node; it grows where data are thin.
   The predictive standard deviation is ``sqrt(spread**2 + bias_se**2)``.
4. **Correlation across axes**: one 6x6 matrix per tag, the Spearman rank correlation of the
   standardised leave-one-out residuals mapped to Pearson (``2 sin(pi rho / 6)``), clipped to be
   positive semi-definite. It does not vary with the covariates (too few data to say more).
5. **Detection probability**: kernel-weighted detection rate of the configurations whose tag faces
   the camera (view angle > 0), with a Beta prior of weight 1 centred on the tag's overall rate;
   its 90 % interval from the Beta posterior with the kernel mass as the number of trials.

Everything is tabulated on a regular (distance, obliquity) grid spanning the data and evaluated by
bilinear interpolation. **No silent extrapolation**: a node is covered when the kernel mass of the
data there (``support``, about the number of configurations within one bandwidth) is at least
``min_support``; a query is inside the model when it lies in the grid and its bilinearly
interpolated support is at least ``min_support``. Outside, the runtime raises
:class:`OutOfRangeError` (or returns NaN when asked to). A tag facing away from the camera
(obliquity beyond +-pi/2) is never detected: that is geometry, not extrapolation.

Files: :meth:`ErrorModel.save` writes netCDF (grid, units, provenance) and JSON (the schema in
docs/errormodel.md, readable by a controller without simgap).

Modules (private, in ``simgap.analysis.errormodel``): ``_fit`` (fitting), ``_model`` (the query
API), ``_io`` (files), ``_check`` (the check on the check half), ``_geometry`` (covariates) and
``_smoothing`` (the local-linear smoother); the public names are re-exported here (``__all__``).
"""

from __future__ import annotations

from simgap.analysis.errormodel._check import (
    check_error_model,
    check_pooled_model,
    evaluate_check_half,
    split_configurations,
)
from simgap.analysis.errormodel._fit import FitSettings, fit_error_model
from simgap.analysis.errormodel._geometry import covariates, perturb, pose_matrices
from simgap.analysis.errormodel._io import FIT_METHODS, SCHEMA, model_paths
from simgap.analysis.errormodel._model import Z90, ErrorModel, OutOfRangeError, TagPoses
from simgap.core.axes import AXES

__all__ = [
    "AXES",
    "FIT_METHODS",
    "SCHEMA",
    "Z90",
    "ErrorModel",
    "FitSettings",
    "OutOfRangeError",
    "TagPoses",
    "check_error_model",
    "check_pooled_model",
    "covariates",
    "evaluate_check_half",
    "fit_error_model",
    "model_paths",
    "perturb",
    "pose_matrices",
    "split_configurations",
]

"""Measured rod records: camera markers from a user's file to the rod on the model's grid.

* ``records``: reading (Parquet or CSV, ``crgpr.io.read_table``), validating and screening
  marker positions (``load_measured`` -> ``Measured``; bad input is one ``MeasuredDataError``
  line naming the file and column);
* ``kinematics``: angles from positions, GP smoothing in time, the angle fit along s (free or
  clamped base) and the rod's q, v, a on the model grid (``smooth_kinematics``; paper
  Sec. III-B, Remark).
Both the missing-physics workflow (``crgpr.discovery``) and learning from camera positions
(``crgpr.learning.camera``) start here; this package imports neither.
"""

from crgpr.measured.kinematics import Kinematics, marker_positions, smooth_kinematics
from crgpr.measured.records import (
    Measured,
    MeasuredDataError,
    ScreenSettings,
    load_measured,
    read_measured,
    validate_frame,
)

__all__ = ["Kinematics", "Measured", "MeasuredDataError", "ScreenSettings", "load_measured",
           "marker_positions", "read_measured", "smooth_kinematics", "validate_frame"]

"""Pose estimation: ArUco detection, PnP, conversion to the global frame, errors."""

"""Rendering: fixture assets, the Mitsuba scene, the OpenCV camera sensor, the camera pipeline."""

"""Rig facts in the report and the comparison are read from the dataset's rig, never retyped."""

from __future__ import annotations

import numpy as np
import xarray as xr
import yaml

from simgap.analysis.gap import distance_thirds
from simgap.analysis.paper import ROTATION_THRESHOLD_RAD, TRANSLATION_THRESHOLD_M
from simgap.analysis.report import dataset_rig, rig_facing_theta_rad
from simgap.analysis.thresholds import PRACTICAL_FLOOR
from simgap.core.config import to_mapping
from simgap.core.rig import load_rig


def test_dataset_rig_reads_experiment_and_capture_attrs():
    assert dataset_rig(xr.Dataset()).links.pin_pitch == load_rig().links.pin_pitch
    exp = xr.Dataset(attrs={"experiment_yaml": "name: x\nrig: {links: {pin_pitch: 0.03}}\n"})
    assert dataset_rig(exp).links.pin_pitch == 0.03
    rig = load_rig(overrides={"links": {"pin_pitch": 0.02}})
    capture = xr.Dataset(attrs={"rig_yaml": yaml.safe_dump(to_mapping(rig))})
    assert dataset_rig(capture).links.pin_pitch == 0.02


def test_tag_facing_angles_and_distance_bins_come_from_the_rig():
    facing = rig_facing_theta_rad(load_rig())
    assert facing[0] == 0.0 and np.isclose(facing[1], np.pi)  # outer face, inner face
    assert list(distance_thirds(np.array(load_rig().grid.p))) == [
        "near (p 0-4)",
        "mid (p 5-9)",
        "far (p 10-14)",
    ]


def test_practical_floor_is_a_tenth_of_the_paper_thresholds():
    tenth = {"m": TRANSLATION_THRESHOLD_M / 10, "rad": ROTATION_THRESHOLD_RAD / 10}
    assert PRACTICAL_FLOOR == tenth

"""The camera's auto exposure: it meters the scene, reaches its target level within its limits,
and the exposure it chose for each frame is kept in the dataset."""

from __future__ import annotations

import numpy as np
import pytest

from simgap.core.rig import CameraModel
from simgap.effects import make_effect
from simgap.effects.image import METER_STRIDE_PX, ImageContext
from simgap.pipeline.experiment import experiment_from_yaml
from simgap.pipeline.sweep import run_experiment
from simgap.scene.lights import BT709_LUMINANCE

CAMERA = CameraModel()


def _luminance(img: np.ndarray) -> float:
    return float(np.mean(img @ np.asarray(BT709_LUMINANCE, np.float32)))


def _ctx(meter: np.ndarray | None = None) -> ImageContext:
    return ImageContext((0, 0), CAMERA, np.random.default_rng(0), meter=meter)


def test_tags_metering_brings_the_crop_to_its_target_and_records_the_ev():
    rng = np.random.default_rng(1)
    crop = rng.uniform(0.0, 40.0, (64, 80, 3)).astype(np.float32)  # a sunlit crop, far above 1
    ae = make_effect("auto_exposure", {"target": 0.18})
    ctx = _ctx()
    out = ae.process(crop, ctx)
    assert _luminance(out) == pytest.approx(0.18, rel=1e-5)  # float32 sums
    assert ctx.record["auto_exposure_ev"] == pytest.approx(np.log2(0.18 / _luminance(crop)))


def test_the_limits_bind_and_a_black_frame_takes_the_longest_exposure():
    ae = make_effect("auto_exposure", {"ev_min": -3.0, "ev_max": 2.0})
    bright = np.full((8, 8, 3), 100.0, np.float32)
    ctx = _ctx()
    np.testing.assert_allclose(ae.process(bright, ctx), 100.0 / 8)  # clipped at -3 EV
    assert ctx.record["auto_exposure_ev"] == -3.0
    ctx = _ctx()
    np.testing.assert_array_equal(ae.process(np.zeros((8, 8, 3), np.float32), ctx), 0.0)
    assert ctx.record["auto_exposure_ev"] == 2.0


def test_frame_and_centre_metering_read_the_whole_frames_grid():
    h, w = CAMERA.height // METER_STRIDE_PX, CAMERA.width // METER_STRIDE_PX
    meter = np.full((h, w, 3), 0.02, np.float32)
    meter[h // 2 - 3 : h // 2 + 3, w // 2 - 3 : w // 2 + 3] = 2.0  # a bright centre
    crop = np.full((16, 16, 3), 1.0, np.float32)
    evs = {}
    for mode in ("tags", "frame", "centre"):
        ctx = _ctx(meter)
        make_effect("auto_exposure", {"metering": mode}).process(crop, ctx)
        evs[mode] = ctx.record["auto_exposure_ev"]
    assert evs["tags"] == pytest.approx(np.log2(0.18))  # the crop alone
    assert evs["frame"] == pytest.approx(np.log2(0.18 / _luminance(meter)), rel=1e-6)
    assert evs["frame"] > evs["centre"] > evs["tags"]  # the centre weighs the bright middle more


ORBIT = """
name: orbit_ae
configurations: {{p: [7], theta_deg: [0]}}
render: {{mode: converged, spp: 4}}
effects:
  black_sky: {{}}
  auto_exposure: {{metering: frame}}
variants:
  - name: full_sun
    effects: {{sun: {{azimuth_deg: 200, elevation_deg: 30}}}}
  - name: quarter_sun
    effects: {{sun: {{azimuth_deg: 200, elevation_deg: 30, irradiance_w_m2: {quarter}}}}}
"""


def test_a_sweep_records_each_frames_exposure_and_compensates_the_light(tmp_path):
    """Rendering is linear in the light: a quarter of the sun meters a quarter, and the camera
    opens up two stops (measured 2.00000; half-float rounding of the cached renders allows
    1e-3), so that both frames reach the same level: the tag is found at the same corners
    (measured identical; 0.01 px allowed). Without a sun the black frame takes ``ev_max``."""
    exp = experiment_from_yaml(ORBIT.format(quarter=1361.0 / 4))
    ds = run_experiment(exp, tmp_path / "cache", show_progress=False)
    ev = ds.auto_exposure_ev.sel(p=7).isel(theta=0, repeat=0)
    assert ev.attrs["units"] == "1" and "stops" in ev.attrs["long_name"]
    full, quarter = float(ev.sel(variant="full_sun")), float(ev.sel(variant="quarter_sun"))
    assert float(ev.sel(variant="baseline")) == 4.0  # no sun under a black sky: ev_max
    assert quarter - full == pytest.approx(2.0, abs=2e-3)
    corners = ds.corners.sel(p=7, tag=0).isel(theta=0, repeat=0)
    np.testing.assert_allclose(
        corners.sel(variant="full_sun"), corners.sel(variant="quarter_sun"), atol=0.01
    )

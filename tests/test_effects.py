"""The effects catalogue: registry, validation, image operations, colour temperature."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel
from simgap.effects import EFFECTS, make_effect
from simgap.effects.image import ImageContext, pipeline_reach_px, run_pipeline
from simgap.effects.scene import cct_to_rgb
from simgap.effects.state import ImageState, VariantState

CANONICAL = {
    "focal_length",
    "principal_point",
    "lens_distortion",
    "camera_mount",
    "turntable_offset",
    "carriage_pitch",
    "tag_scale",
    "defocus",
    "sensor_noise",
    "exposure",
    "tag_gloss",
    "lighting",
    "jpeg",
    "detector_refinement",
}


def test_registry_has_the_catalogue_with_stages_and_docs():
    assert CANONICAL <= set(EFFECTS)
    for name, cls in EFFECTS.items():
        assert cls.name == name
        assert cls.stage in ("scene", "geometry", "image", "estimation")
        assert cls.__doc__ and len(cls.__doc__.split()) >= 5, name
        params = cls.Params()  # defaults are valid
        assert dataclasses.is_dataclass(params)
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(params, dataclasses.fields(params)[0].name, None)


@pytest.mark.parametrize(
    "name, params, message",
    [
        (
            "tag_gloss",
            {"alpha": 3},
            "x.yaml: variants[0].effects.tag_gloss.alpha: expected 0 < alpha",
        ),
        ("sensor_noise", {"full_well_e": "lots"}, "sensor_noise.full_well_e: expected a number"),
        ("lens_distortion", {"k4": 0.1}, "lens_distortion.k4: unknown key; expected one of"),
        ("tag_glos", {}, "tag_glos: unknown effect; expected one of"),
        ("lighting", {"type": "laser"}, "lighting.type: expected one of 'area', 'point', 'spot'"),
    ],
)
def test_bad_effect_parameters_name_file_key_and_expectation(name, params, message):
    with pytest.raises(ConfigError) as exc:
        make_effect(name, params, where="x.yaml: variants[0].effects.")
    assert message in str(exc.value)


def test_effects_change_only_their_stage():
    base = VariantState()
    for name, cls in EFFECTS.items():
        out = cls(cls.Params()).apply(base)
        changed = {
            f.name for f in dataclasses.fields(out) if getattr(out, f.name) != getattr(base, f.name)
        }
        stage = {"geometry": "scene"}.get(cls.stage, cls.stage)
        # a lens distortion and a camera's response also tell the estimator what they are (its
        # calibration; the response it reads levels through)
        both = name in ("lens_distortion", "camera_response")
        allowed = {stage, "estimation"} if both else {stage}
        assert changed <= allowed, (name, changed)


def test_a_wide_blur_widens_the_render_margin(rig, tmp_path):
    """The render region reaches as far as the camera pipeline spreads a pixel (3 sigma of a
    blur, half a motion blur and one pixel), so that a wide blur never pulls in the surround."""
    from simgap.pipeline.cache import Cache
    from simgap.pipeline.variant import VariantPipeline

    state = VariantState()
    for name, params, reach in [("blur", {"sigma_px": 0.7}, 2.1), ("blur", {"sigma_px": 9.0}, 27.0),
                                ("motion_blur", {"length_px": 40.0}, 21.0)]:  # fmt: skip
        wide = make_effect(name, params).apply(state)
        assert pipeline_reach_px(wide.image) == pytest.approx(reach)
        pipe = VariantPipeline(rig, wide, (0, 1), 24, Cache(tmp_path), "assets")
        assert pipe.margin_px == max(24, int(np.ceil(reach)))


def _ctx(seed=0, offset=(0, 0)):
    return ImageContext(offset, CameraModel(), np.random.default_rng(seed))


def test_sensor_noise_is_seeded_and_has_the_modelled_variance():
    img = np.full((64, 64, 3), 0.25, np.float32)
    state = (
        make_effect("sensor_noise", {"full_well_e": 1000, "read_noise_e": 5})
        .apply(VariantState())
        .image
    )
    assert state.stochastic
    state = dataclasses.replace(state, encoding="linear")
    op = make_effect("sensor_noise", {"full_well_e": 1000, "read_noise_e": 5})
    a = op.process(img, _ctx(1))
    assert np.array_equal(a, op.process(img, _ctx(1)))
    assert not np.array_equal(a, op.process(img, _ctx(2)))
    # variance in electrons: shot (250 e-) + read (25 e-^2) -> std = sqrt(275)/1000 in linear units;
    # 12288 samples give the std to ~1 %: tolerance 5 %
    assert abs(a.std() - np.sqrt(275.0) / 1000.0) < 0.05 * np.sqrt(275.0) / 1000.0
    assert abs(a.mean() - 0.25) < 1e-3


def test_exposure_gamma_and_quantisation():
    img = np.full((4, 4, 3), 0.25, np.float32)
    state = VariantState()
    for name, params in [("exposure", {"ev": 1.0}), ("gamma", {"encoding": "linear"})]:
        state = make_effect(name, params).apply(state)
    out = run_pipeline(img, state.image, _ctx())
    assert out.dtype == np.uint8 and np.all(out == 128)  # 0.25 * 2 = 0.5 -> round(127.5) = 128
    gamma = make_effect("gamma", {"encoding": "gamma", "gamma": 2.0}).apply(VariantState()).image
    assert np.all(run_pipeline(img, gamma, _ctx()) == 128)  # sqrt(0.25) = 0.5


def test_vignetting_depends_on_where_the_crop_is():
    img = np.ones((16, 16, 3), np.float32)
    op = make_effect("vignetting", {"strength": 0.5})
    centre = op.process(img, ImageContext((952, 532), CameraModel(), None))
    corner = op.process(img, ImageContext((0, 0), CameraModel(), None))
    # pixel (0, 0) is 1 px short of the corner radius (cx = 959.5 of 1920): gain 0.50123
    assert centre.min() > 0.999 and corner[0, 0, 0] == pytest.approx(0.5, abs=2e-3)


def test_jpeg_on_an_aligned_crop_equals_jpeg_on_the_frame():
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, (96, 128, 3), dtype=np.uint8)
    op = make_effect("jpeg", {"quality": 60})
    whole = op.process(frame, _ctx())
    crop = op.process(frame[32:80, 48:112].copy(), _ctx(offset=(48, 32)))
    # 16-px aligned crop: identical 8x8 blocks and 2x2 chroma cells, except where the chroma
    # upsampling filter reads across the crop's edge (outermost pixel ring)
    np.testing.assert_array_equal(crop[1:-1, 1:-1], whole[33:79, 49:111])


def test_cct_to_rgb():
    r, g, b = cct_to_rgb(3000)
    assert r > g > b
    # the Planckian locus at 6504 K lies near D65 (the sRGB white) but off it by its Duv:
    # measured channel spread 5.8 %
    white = np.array(cct_to_rgb(6504))
    assert np.ptp(white) < 0.07
    assert cct_to_rgb(None) == (1.0, 1.0, 1.0)
    assert float(np.dot(cct_to_rgb(4000), [0.2126, 0.7152, 0.0722])) == pytest.approx(1.0)


def test_state_image_stochastic_flag():
    assert not ImageState().stochastic
    assert make_effect("sensor_noise", {}).apply(VariantState()).image.stochastic


def test_material_override_with_a_new_type_replaces_the_template_entry():
    from simgap.render.mitsuba_scene import bsdf
    from simgap.scene import Coating, Conductor, TagPrint

    bare = make_effect("fixture_material", {"slot": "node", "finish": "bare"})
    spec = bare.apply(VariantState()).scene.spec
    assert spec.materials["node"] == Conductor(material="Al", alpha=0.25)
    assert bsdf(spec.materials["node"]) == {
        "type": "roughconductor",
        "material": "Al",
        "alpha": 0.25,
    }
    state = make_effect("tag_material", {"ink": 0.05, "paper": 0.7}).apply(VariantState())
    state = make_effect("tag_gloss", {"alpha": 0.1}).apply(state)
    tag = state.scene.spec.tag
    assert tag == TagPrint(ink=0.05, paper=0.7, coating=Coating(alpha=0.1, int_ior=1.49))
    light = make_effect("lighting", {"type": "point", "power": 2.0}).apply(VariantState())
    key = light.scene.spec.lights["key"]
    assert key.type == "point" and key.intensity == 2.0

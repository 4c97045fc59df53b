"""The renderer-agnostic scene description (simgap.scene) and its Mitsuba converter."""

from __future__ import annotations

import pytest

from simgap.core.config import ConfigError
from simgap.render.mitsuba_scene import bsdf
from simgap.scene import Conductor, Diffuse, Plastic, TagPrint, load_scene_spec


def test_template_reads_into_typed_materials():
    spec = load_scene_spec()
    assert spec.materials["aluminium"] == Conductor(material="Al", alpha=0.25)
    assert spec.materials["node"] == Diffuse(reflectance=0.45)
    assert spec.tag == TagPrint(ink=0.03, paper=0.8)
    assert set(spec.lights) == {"key", "ambient"}


@pytest.mark.parametrize(
    "entry",
    [
        {"type": "diffuse", "reflectance": 0.3},
        {"type": "roughconductor", "material": "Al", "alpha": 0.25},
        {"type": "conductor", "material": "Au"},
        {"type": "roughplastic", "diffuse_reflectance": 0.2, "alpha": 0.3, "int_ior": 1.49},
        {"type": "plastic", "diffuse_reflectance": 0.2, "int_ior": 1.5},
    ],
)
def test_converter_gives_back_the_template_entry(entry):
    spec = load_scene_spec({"materials": {"node": entry}})
    assert bsdf(spec.materials["node"]) == entry


def test_rough_entry_without_alpha_takes_mitsubas_default():
    spec = load_scene_spec({"materials": {"node": {"type": "roughplastic"}}})
    assert spec.materials["node"] == Plastic(alpha=0.1)


@pytest.mark.parametrize(
    "overrides, message",
    [
        ({"materials": {"node": {"type": "velvet"}}}, "materials.node.type: expected one of"),
        ({"materials": {"node": {"type": "diffuse", "alpha": 0.2}}}, "materials.node.alpha"),
        ({"materials": {"table": {"reflectance": float("nan")}}}, "finite"),
        ({"materials": {"tag": {"texture_filter": "cubic"}}}, "materials.tag.texture_filter"),
        ({"materials": {"tag": {"type": "roughconductor"}}}, "materials.tag.type"),
        ({"lights": {"key": {"cutoff_deg": 95}}}, "lights.key"),
        ({"bogus": 1}, "bogus: unknown key"),
    ],
)
def test_bad_scene_names_the_key(overrides, message):
    with pytest.raises(ConfigError, match=message):
        load_scene_spec(overrides)


def test_tag_keeps_ink_and_paper_across_a_type_change():
    spec = load_scene_spec({"materials": {"tag": {"type": "roughplastic", "alpha": 0.2}}})
    assert spec.tag.ink == 0.03 and spec.tag.paper == 0.8 and spec.tag.coating.alpha == 0.2

"""Albedo demodulation of a sticker (issue 28) on synthetic renders with a known expectation.

The synthetic sticker (:mod:`simgap.render.synthetic_sticker`): a 60 px, 10 x 10-cell print
(ink 0.03, paper 0.8, box-filtered), stratified samples whose light-sampling noise has a relative
standard deviation of 0.6 per sample. That value puts the raw 4-spp sticker noise at about 21 DN,
the figure measured on the Mitsuba renders in issue 28.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simgap.render.demodulate import FULL_COVERAGE, StickerSamples, Treatment, demodulate
from simgap.render.synthetic_sticker import Shadow, quadratic_irradiance, synthetic_sticker

NOISE = 0.6
ORIGIN, SIZE = (100.37, 200.71), 60.0
CENTRE = (ORIGIN[0] + SIZE / 2, ORIGIN[1] + SIZE / 2)


def _noise_free(samples: StickerSamples, truth: np.ndarray) -> StickerSamples:
    """The same sticker with its rendered mean at its expectation and no sample variance."""
    return dataclasses.replace(samples, radiance=truth, sample_variance=np.zeros_like(truth))


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


@pytest.mark.parametrize(("spp", "bound"), [(4, 0.02), (16, 0.01)])
def test_flat_print_under_smooth_light_converges(spp, bound):
    # bound: the fit's expected relative error is sqrt(k / N) x the pixel's relative noise
    # (weighted least squares), k = 6 coefficients, N = 3481 px, noise 0.6 / sqrt(spp):
    # 1.25 % at 4 spp, 0.62 % at 16; the bounds leave 1.6x for the seed
    s = synthetic_sticker(np.random.default_rng(spp), spp, relative_noise=NOISE)
    result = demodulate(s.samples)
    assert result.treatment is Treatment.SMOOTH and not result.needs_more_samples
    assert result.fits[0].order == 2  # the irradiance is quadratic
    full = s.samples.coverage >= FULL_COVERAGE
    err = (result.radiance - s.truth)[full]
    raw = (s.samples.radiance - s.truth)[full]
    assert _rms(err / s.truth[full]) < bound
    assert _rms(raw) / _rms(err) >= 10.0


def test_noise_free_demodulation_is_exact():
    s = synthetic_sticker(np.random.default_rng(0), 4, relative_noise=NOISE)
    result = demodulate(_noise_free(s.samples, s.truth))
    assert result.treatment is Treatment.SMOOTH
    full = s.samples.coverage >= FULL_COVERAGE
    # exact but for float64 rounding of a 6-coefficient least-squares fit (border: next test)
    np.testing.assert_allclose(result.radiance[full], s.truth[full], rtol=0, atol=1e-9)


def test_mixed_border_pixels_are_exact_without_noise():
    s = synthetic_sticker(np.random.default_rng(1), 16, relative_noise=NOISE)
    mixed = s.samples.coverage < FULL_COVERAGE
    assert mixed.sum() > 100 and s.samples.coverage[mixed].min() < 0.5
    samples = _noise_free(s.samples, s.truth)
    # the background part at its expectation (0.15, the generator's background radiance)
    samples = dataclasses.replace(samples, background=np.full_like(s.truth, 0.15))
    result = demodulate(samples)
    np.testing.assert_allclose(result.radiance[mixed], s.truth[mixed], rtol=0, atol=1e-9)
    # without the background part a mixed pixel keeps its rendered value
    bare = demodulate(dataclasses.replace(s.samples, background=None))
    np.testing.assert_array_equal(bare.radiance[mixed], s.samples.radiance[mixed])


def test_shadow_edge_is_detected_and_the_pixels_kept():
    normal = (0.6, 0.8)
    offset = normal[0] * (CENTRE[0] + 3) + normal[1] * (CENTRE[1] - 2)
    for seed in range(3):
        s = synthetic_sticker(
            np.random.default_rng(seed), 16, relative_noise=NOISE,
            shadow=Shadow(normal, offset, 0.2),
        )  # fmt: skip
        result = demodulate(s.samples)
        assert result.treatment is Treatment.FALLBACK and result.needs_more_samples
        assert result.reason
        # both sides keep the path-traced pixels: no smooth fit biases them
        np.testing.assert_array_equal(result.radiance, s.samples.radiance)


def test_strong_additive_highlight_is_detected():
    # radiance = albedo x irradiance + a broad lobe independent of the albedo (a glint on a
    # laminate) breaks the model; a lobe peaking at 5 % of the paper's radiance (0.02 against
    # 0.8 x 0.5) is flagged. A weaker one is not always (issue 28 report: its bias).
    def lobe(x, y):
        return 0.02 * np.exp(-((x - CENTRE[0] - 8) ** 2 + (y - CENTRE[1] + 5) ** 2) / 450.0)

    for spp in (4, 16):
        s = synthetic_sticker(np.random.default_rng(spp), spp, relative_noise=NOISE, highlight=lobe)
        result = demodulate(s.samples)
        assert result.treatment is Treatment.FALLBACK
        np.testing.assert_array_equal(result.radiance, s.samples.radiance)


@pytest.mark.parametrize(("spp", "bound"), [(4, 0.03), (16, 0.016)])
def test_a_coated_print_separates_a_smooth_specular_field(spp, bound):
    """A laminate: radiance = albedo x a quadratic irradiance + a quadratic specular field (5 %
    of the paper's radiance at the centre). Noise-free, the two-field fit is exact; at 4 and 16
    spp its relative error over 10 seeds was 1.0-2.1 % and 0.7-1.1 % (the matte model flags
    every one of them), at least 11x below the raw noise. Bounds: about 1.5x the largest."""
    highlight = quadratic_irradiance(CENTRE, SIZE / 2, level=0.05)
    s = synthetic_sticker(np.random.default_rng(0), spp, relative_noise=NOISE, highlight=highlight)
    full = s.samples.coverage >= FULL_COVERAGE
    exact = demodulate(dataclasses.replace(_noise_free(s.samples, s.truth), coated=True))
    np.testing.assert_allclose(exact.radiance[full], s.truth[full], rtol=0, atol=1e-9)
    result = demodulate(dataclasses.replace(s.samples, coated=True))
    assert result.treatment is Treatment.SMOOTH
    err = (result.radiance - s.truth)[full]
    assert _rms(err / s.truth[full]) < bound
    assert _rms((s.samples.radiance - s.truth)[full]) / _rms(err) >= 10.0
    assert demodulate(s.samples).treatment is Treatment.FALLBACK


def test_smooth_light_is_not_flagged():
    # false alarms: FALSE_ALARM_PROBABILITY = 1e-3 per sticker; 10 seeds at 4 spp should give none
    for k in range(10):
        s = synthetic_sticker(np.random.default_rng(100 + k), 4, relative_noise=NOISE)
        assert demodulate(s.samples).treatment is Treatment.SMOOTH


def test_bad_input_names_the_field():
    s = synthetic_sticker(np.random.default_rng(0), 4)
    with pytest.raises(ValueError, match="albedo: expected shape"):
        dataclasses.replace(s.samples, albedo=s.samples.albedo[:-1])
    with pytest.raises(ValueError, match="spp: expected at least 2"):
        dataclasses.replace(s.samples, spp=1)

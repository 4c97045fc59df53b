"""Is a tag the orbital study lost lost to the light, or to the renderer's noise?

Under a sun behind the node, a tag facing the camera is lit only indirectly: by the sliver of the
Earth below the turntable's rim and by sunlight the aluminium carriage and rail reflect onto it
(a caustic). Path tracing renders such light as rare bright samples ("fireflies"); the converged
render's smooth model rejects them and keeps the sticker path traced at four times its samples,
speckled. A detection lost there may be the renderer's, not the camera's.

For every visible configuration a result dataset lost (repeat 0), this script re-renders the frame
of its variant through the same camera pipeline, path traced at ``--spp`` samples per pixel (a
reference where fireflies average out), and prints whether the tag is found there, with the
sticker's converged treatment in the study's render and the share of the region's light that its
brightest 1 % of pixels hold at the study's samples (1 % where the light is smooth; fireflies
raise it). A tag found in the reference was lost to render noise.

``--item VARIANT:TAG:P:THETA_DEG`` (repeatable) checks given items instead, found or lost, e.g.
tags the study finds where an earlier renderer lost them. Each line then also holds the
region's mean linear radiance in the study's render (read from ``--cache``, the study's render
cache, when it holds it) and in the reference, over the middle half of the region along each
axis (the sticker), and their ratio: a converged render that drops or adds light shows there,
while fireflies only scatter the reference's pixels, not its mean; and the reference's scatter
about the study's render (its noise, or structure the study's smooth light lacks), and where
both find the tag, the largest difference of a corner coordinate between them (px).

Usage: ``python benchmarks/orbital_lost_tags.py results/orbital/orbital.nc [--spp 256]
[--cache ~/.cache/simgap] [--item ...]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from simgap.effects import make_effect
from simgap.pipeline.cache import Cache
from simgap.pipeline.experiment import experiment_from_yaml
from simgap.pipeline.variant import VariantPipeline, assets_hash
from simgap.render.converged import converged_pixels
from simgap.results.dataset import read_netcdf


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("result", type=Path, help="orbital study dataset (simgap run)")
    parser.add_argument("--spp", type=int, default=256, help="reference samples per pixel")
    parser.add_argument("--cache", type=Path, help="the study's render cache (default: a new one)")
    parser.add_argument(
        "--item", action="append", default=[], help="VARIANT:TAG:P:THETA_DEG to check instead"
    )
    args = parser.parse_args()
    ds = read_netcdf(args.result)
    exp = experiment_from_yaml(ds.attrs["experiment_yaml"], source=str(args.result))
    states = dict(exp.variant_states())
    tags = tuple(int(t) for t in ds.tag.values)
    items = [_parse_item(text, ds, tags) for text in args.item] or _lost_items(ds, tags)
    study_cache = Cache(args.cache) if args.cache else None
    cache = Cache(Path(tempfile.mkdtemp(prefix="simgap-lost-")))
    assets = assets_hash()
    print(f"{len(items)} items (tag x configuration); reference: path traced at {args.spp} spp")
    print(
        "variant | tag | p | theta | study | study's sticker | brightest 1 % hold | reference "
        "| study / reference mean radiance | reference's scatter "
        "| largest corner shift (px) | seconds"
    )
    recovered = 0
    for name, tag, p, theta in items:
        t = tags.index(tag)
        state = states[name]
        margin = exp.render.margin_px
        study = VariantPipeline(exp.rig_model, state, tags, margin, study_cache or cache, assets)
        scene = study.scene()
        scene.set_pose(p, theta)
        region = study.region(p, theta)
        converged = converged_pixels(scene, region.pixels(), 1)
        samples = scene.render_pixels(region.pixels(), 1)
        lum = np.sort(samples.mean(axis=1))[::-1]
        share = float(lum[: max(len(lum) // 100, 1)].sum() / max(lum.sum(), 1e-12))
        ours = study.run(p, theta, 0, 0)
        in_study = bool(ours.detected[t])
        t0 = time.perf_counter()
        quality = {"spp": args.spp, "mode": "path", "max_depth": exp.render.max_depth}
        reference = make_effect("render_quality", quality).apply(state)
        pipe = VariantPipeline(exp.rig_model, reference, tags, margin, cache, assets)
        theirs = pipe.run(p, theta, 0, 0)
        found = bool(theirs.detected[t])
        shift = float(np.abs(ours.corners[t] - theirs.corners[t]).max())  # NaN unless both
        recovered += found
        ratio, scatter = _compare(study.hdr(p, theta, 0)[0], pipe.hdr(p, theta, 0)[0])
        print(
            f"{name} | {tag} | {p} | {np.degrees(theta):.0f} | "
            f"{'found' if in_study else 'lost'} | {converged.treatments.get(tag, '-')} | "
            f"{share:.1%} | {'found' if found else 'lost'} | {ratio:.3f} | {scatter:.1%} | "
            f"{shift:.2f} | "
            f"{time.perf_counter() - t0:.0f}"
        )
    print(f"found in the reference: {recovered} of {len(items)}")


def _lost_items(ds, tags) -> list[tuple[str, int, int, float]]:
    """Every visible (variant, tag, p, theta) the dataset lost in repeat 0."""
    visible = ds.visible.broadcast_like(ds.detected).astype(bool).isel(repeat=0)
    lost = visible & ~ds.detected.astype(bool).isel(repeat=0)
    return [
        (str(ds.variant.values[v]), tags[t], int(ds.p.values[i]), float(ds.theta.values[j]))
        for v, t, i, j in np.argwhere(lost.values)
    ]


def _parse_item(text: str, ds, tags) -> tuple[str, int, int, float]:
    """``VARIANT:TAG:P:THETA_DEG`` as (variant, tag, p, theta in rad), checked against ``ds``."""
    name, tag, p, theta_deg = text.rsplit(":", 3)
    if name not in ds.variant.values or int(tag) not in tags or int(p) not in ds.p.values:
        raise SystemExit(f"--item {text}: no such variant, tag or p in the dataset")
    return name, int(tag), int(p), float(np.radians(float(theta_deg)))


def _compare(study: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """The study's over the reference's mean radiance, and the reference's pixel scatter.

    Both over the middle half of the region along each axis (the sticker). The scatter is the
    standard deviation, over pixels the study's render holds light in, of the reference's
    luminance over the study's (the study's carries the print's pattern; what is left is the
    reference's noise and any structure the study's smooth light lacks), as a fraction.
    """
    h, w = study.shape[:2]
    middle = (slice(h // 4, h - h // 4), slice(w // 4, w - w // 4))
    s, r = study[middle].mean(axis=-1), reference[middle].mean(axis=-1)
    lit = s > 0.05 * s.max()
    return float(s.mean() / r.mean()), float(np.std(r[lit] / s[lit]) / np.mean(r[lit] / s[lit]))


if __name__ == "__main__":
    main()

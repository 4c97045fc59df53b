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

Usage: ``python benchmarks/orbital_lost_tags.py results/orbital/orbital.nc [--spp 256]``
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
from simgap.pipeline.variant import VariantPipeline
from simgap.render.converged import converged_pixels
from simgap.results.dataset import read_netcdf


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("result", type=Path, help="orbital study dataset (simgap run)")
    parser.add_argument("--spp", type=int, default=256, help="reference samples per pixel")
    args = parser.parse_args()
    ds = read_netcdf(args.result)
    exp = experiment_from_yaml(ds.attrs["experiment_yaml"], source=str(args.result))
    states = dict(exp.variant_states())
    tags = tuple(int(t) for t in ds.tag.values)
    visible = ds.visible.broadcast_like(ds.detected).astype(bool).isel(repeat=0)
    lost = visible & ~ds.detected.astype(bool).isel(repeat=0)
    cache = Cache(Path(tempfile.mkdtemp(prefix="simgap-lost-")))
    print(
        f"{int(lost.sum())} lost items (tag x configuration); "
        f"reference: path traced at {args.spp} spp"
    )
    print("variant | tag | p | theta | study's sticker | brightest 1 % hold | reference | seconds")
    recovered = 0
    for v, t, i, j in np.argwhere(lost.values):
        name, tag = str(ds.variant.values[v]), tags[t]
        p, theta = int(ds.p.values[i]), float(ds.theta.values[j])
        state = states[name]
        study = VariantPipeline(exp.rig_model, state, tags, exp.render.margin_px, cache, "")
        scene = study.scene()
        scene.set_pose(p, theta)
        region = study.region(p, theta)
        converged = converged_pixels(scene, region.pixels(), 1)
        samples = scene.render_pixels(region.pixels(), 1)
        lum = np.sort(samples.mean(axis=1))[::-1]
        share = float(lum[: max(len(lum) // 100, 1)].sum() / max(lum.sum(), 1e-12))
        t0 = time.perf_counter()
        quality = {"spp": args.spp, "mode": "path", "max_depth": exp.render.max_depth}
        reference = make_effect("render_quality", quality).apply(state)
        pipe = VariantPipeline(exp.rig_model, reference, tags, exp.render.margin_px, cache, "")
        found = bool(pipe.run(p, theta, 0, 0).detected[t])
        recovered += found
        print(
            f"{name} | {tag} | {p} | {np.degrees(theta):.0f} | "
            f"{converged.treatments.get(tag, '-')} | {share:.1%} | "
            f"{'found' if found else 'lost'} | {time.perf_counter() - t0:.0f}"
        )
    print(f"found in the reference: {recovered} of {int(lost.sum())}")


if __name__ == "__main__":
    main()

"""Settings of the gap diagnosis: its splits, subsample sizes, render seeds and render mode."""

from __future__ import annotations

from dataclasses import dataclass

from simgap.analysis.thresholds import EXPLAINED_REDUCTION
from simgap.pipeline.experiment import Experiment
from simgap.pipeline.experiment_settings import DEFAULT_SPP

#: Samples per pixel of a diagnosis' path-traced simulation of an experiment that renders
#: converged: path tracing's own default (the study's setting before converged rendering;
#: docs/validation.md lists the validation seeds run with it).
PATH_SIMULATION_SPP = DEFAULT_SPP["path"]


@dataclass(frozen=True)
class DiagnoseSettings:
    """Settings of the diagnosis (the defaults are the diagnosis's; see each attribute)."""

    #: Share of the comparable items used to fit effects (the fit split).
    fit_fraction: float = 0.5
    #: Share used to rank, add, simplify and prune effects (the choose split). The rest is the
    #: measure split: the reduction is measured there only, never on items that fitted
    #: or chose the model.
    choose_fraction: float = 0.25
    #: Seed of the split and the subsamples.
    seed: int = 0
    #: Items used when fitting a candidate by simulation (a subsample of the fit split).
    max_sim_fit_items: int = 40
    #: Most items of the choose split (all candidates are scored on them).
    max_choose_items: int = 80
    #: Pose-gap reduction (choose split) below which a significant pose gap is reported as
    #: unexplained.
    explained_reduction: float = EXPLAINED_REDUCTION
    #: Re-run the full pipeline with the selected effects to confirm the reduction.
    confirm: bool = True
    #: A capture with fewer configurations is simulated at several render seeds, until it has
    #: this many simulated frames (at most ``max_render_seeds`` per configuration): path
    #: traced, the render noise of each configuration is then measured, and a far, oblique tag
    #: whose pose moves millimetres with its render noise no longer decides the choice between
    #: effects (measured on the 9-configuration public sample:
    #: docs/results/sample_focal_render_seeds.md); converged, the seeds keep the capture's frames
    #: a pose (:meth:`render_seeds`). Larger captures are simulated with the experiment's own
    #: repeats (usually one); their medians over many items are robust to one noisy
    #: item.
    min_simulated_frames: int = 36
    #: Most render seeds per configuration.
    max_render_seeds: int = 4
    #: Simulate an experiment that renders converged (the baseline's) converged too; off: path
    #: traced at :data:`PATH_SIMULATION_SPP` (how the earlier blind seeds ran:
    #: docs/results/design_evidence.md#settings). A noise-free simulation would compare a noisy
    #: capture's far, oblique tags with poses the capture cannot have (PnP shifts their depth
    #: under corner noise: +10 mm at 16 spp, benchmarks/far_tag_noise_bias.py), so each converged
    #: simulated pose is moved by the shift the capture's corner noise gives it
    #: (:func:`simgap.diagnosis.items.with_noise_shift`; the public sample-focal's ty gap: 3.7
    #: standard errors without it, 4.7 with it, 5.3 path traced). Blind seeds: docs/validation.md.
    converged_simulation: bool = True

    def simulation(self, exp: Experiment) -> Experiment:
        """``exp`` as the diagnosis simulates it (see :attr:`converged_simulation`).

        An experiment that already path traces is left as it is.
        """
        if exp.render.mode == "converged" and not self.converged_simulation:
            return exp.with_render(mode="path", spp=PATH_SIMULATION_SPP)
        return exp

    def render_seeds(self, configurations: int) -> int:
        """Render seeds for the simulation of a capture of ``configurations`` configurations.

        The same rule for a converged simulation (:attr:`converged_simulation`), although its
        seeds differ little (0.09 mm in ty over the baseline,
        docs/results/converged_render_step8.md#step-4): a capture's frames are compared with as many
        simulated repeats only (:func:`simgap.diagnosis.items.repeats_of_simulation`), and one
        seed would keep only the first of the public sample-focal's 4 frames a pose. Its
        per-item pose noise comes from the corners instead
        (:func:`simgap.diagnosis.items.with_propagated_noise`). A capture of 36 configurations
        or more gets one seed.
        """
        wanted = -(-self.min_simulated_frames // max(configurations, 1))
        return int(min(max(wanted, 1), self.max_render_seeds))

"""Settings of the gap diagnosis: its splits, subsample sizes and render seeds."""

from __future__ import annotations

from dataclasses import dataclass

from simgap.analysis.thresholds import EXPLAINED_REDUCTION


@dataclass(frozen=True)
class DiagnoseSettings:
    """Settings of the diagnosis (the defaults are the diagnosis's; see each attribute)."""

    #: Share of the visible configurations used to fit effects (the fit split).
    fit_fraction: float = 0.5
    #: Share used to rank, add, simplify and prune effects (the choose split). The rest is the
    #: report split: the reduction is measured there only, never on configurations that fitted
    #: or chose the model.
    choose_fraction: float = 0.25
    #: Seed of the split and the subsamples.
    seed: int = 0
    #: Configurations used when fitting a candidate by simulation (a subsample of the fit split).
    max_sim_fit_items: int = 40
    #: Most configurations of the choose split (all candidates are scored on them).
    max_choose_items: int = 80
    #: Pose-gap reduction (choose split) below which a significant pose gap is reported as
    #: unexplained.
    explained_reduction: float = EXPLAINED_REDUCTION
    #: Re-run the full pipeline with the selected effects to confirm the reduction.
    confirm: bool = True
    #: A capture with fewer configurations is simulated at several render seeds, until it has
    #: this many simulated frames (at most ``max_render_seeds`` per configuration): the render
    #: noise of each configuration is then measured, and a far, oblique tag whose pose moves
    #: millimetres with its render noise no longer decides the choice between effects (measured
    #: on the 9-configuration public sample: docs/results/sample_focal_render_seeds.md). Larger
    #: captures are simulated with the experiment's own repeats (usually one); their medians
    #: over many items are robust to one noisy configuration.
    min_simulated_frames: int = 36
    #: Most render seeds per configuration.
    max_render_seeds: int = 4

    def render_seeds(self, configurations: int, render_mode: str = "path") -> int:
        """Render seeds for the simulation of a capture of ``configurations`` configurations.

        One for a ``converged`` render (``render.mode``): its demodulated sticker pixels carry
        almost no Monte Carlo noise to average (two render seeds of the baseline sweep differ by
        0.085 mm in ty and 0.25-0.41 mrad in rotation; docs/results/converged_render_step3.md),
        so the simulation's noise is the modelled camera's. A sticker that falls back to path
        tracing, and the pixels off the stickers, keep their path-traced noise.
        """
        if render_mode == "converged":
            return 1
        wanted = -(-self.min_simulated_frames // max(configurations, 1))
        return int(min(max(wanted, 1), self.max_render_seeds))
